"""The return judge, the behaviour judge's burn-in and the one tie rule (no training)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

from engine.candidates import Candidate
from engine.envs import make_env, restore
from engine.errors import InputError
from engine.pipeline import run_tournament
from engine.rl import returns as returns_module
from engine.rl.behaviour import RolloutOptions, occupancy_scores, visited_states
from engine.rl.returns import ReturnOptions, candidate_returns, return_scores
from engine.tournament import ScoreJudge, score_winner
from engine.treefile import TreeDocument

Policy = Callable[[np.ndarray], np.ndarray]


@pytest.fixture(scope="module")
def hopper() -> TreeDocument:
    return run_tournament(env_id="Hopper-v5", n_candidates=4, p=0.9, seed=2, teacher="standing")


def _still(obs: np.ndarray) -> np.ndarray:
    return np.zeros(3)


def _manual_return(doc: TreeDocument, i: int, horizon: int) -> float:
    """The env's own reward summed by hand from candidate ``i``'s exact state."""
    env = make_env(doc.env_id)
    env.reset(seed=0)
    c = doc.candidates[i]
    restore(env, c.qpos, c.qvel)
    total = 0.0
    for _ in range(horizon):
        _, r, terminated, _, _ = env.step(np.zeros(3))
        total += float(r)
        if terminated:
            break
    env.close()
    return total


def test_the_return_is_the_envs_own_reward_to_go(hopper: TreeDocument) -> None:
    options = ReturnOptions(rollouts=5, horizon=30, noise=0.0)
    got = candidate_returns(_still, hopper, options)
    assert got.shape == (4, 5)
    for i in range(4):  # without perturbation all K rollouts are the one trajectory
        np.testing.assert_allclose(got[i], _manual_return(hopper, i, 30), rtol=1e-9)


@pytest.mark.parametrize("noise", [None, 0.05])
def test_perturbed_rollouts_are_seeded_and_differ(
    hopper: TreeDocument, noise: float | None
) -> None:
    options = ReturnOptions(rollouts=5, horizon=20, noise=noise, seed=3)
    first = candidate_returns(_still, hopper, options)
    np.testing.assert_array_equal(first, candidate_returns(_still, hopper, options))
    assert (first.std(axis=1) > 0).all()  # K different starts, not K copies
    other = candidate_returns(_still, hopper, ReturnOptions(5, 20, noise, seed=4))
    assert not np.array_equal(first, other)


def test_return_scores_are_cached_by_checkpoint_content(
    hopper: TreeDocument, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    options = ReturnOptions(rollouts=5, horizon=10)
    first = return_scores(_still, hopper, options, run_dir=tmp_path, checkpoint_digest="ab" * 32)
    assert first == pytest.approx(
        dict(
            zip(
                [c.id for c in hopper.candidates],
                candidate_returns(_still, hopper, options).mean(1),
                strict=True,
            )
        )
    )
    monkeypatch.setattr(returns_module, "candidate_returns", _no_simulation)
    again = return_scores(_still, hopper, options, run_dir=tmp_path, checkpoint_digest="ab" * 32)
    assert again == first  # read from the cache, not simulated
    with pytest.raises(AssertionError, match="simulated"):  # another checkpoint's content
        return_scores(_still, hopper, options, run_dir=tmp_path, checkpoint_digest="cd" * 32)
    with pytest.raises(AssertionError, match="simulated"):  # other candidates
        other = run_tournament(env_id="Hopper-v5", n_candidates=4, p=0.9, seed=5, teacher="good")
        return_scores(_still, other, options, run_dir=tmp_path, checkpoint_digest="ab" * 32)


def _no_simulation(*args: object) -> np.ndarray:
    raise AssertionError("simulated instead of reading the cache")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"rollouts": 4}, "rollouts >= 5"),
        ({"horizon": 0}, "horizon >= 1"),
        ({"noise": -1.0}, "noise"),
    ],
)
def test_return_options_are_validated(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(InputError, match=message):
        ReturnOptions(**kwargs)  # type: ignore[arg-type]


def test_burn_in_is_validated() -> None:
    with pytest.raises(InputError, match="burn_in >= 0"):
        RolloutOptions(burn_in=-1)


def test_a_burn_in_longer_than_every_episode_leaves_no_preference(hopper: TreeDocument) -> None:
    visited = visited_states(_still, "Hopper-v5", RolloutOptions(episodes=2, burn_in=10_000))
    assert visited.shape == (0, 6)
    assert set(occupancy_scores(visited, hopper).values()) == {0.0}


def _random_policy(n_actions: int) -> Policy:
    rng = np.random.default_rng(0)
    return lambda obs: rng.uniform(-1.0, 1.0, n_actions)


def _frozen_policy(n_actions: int) -> Policy:
    return lambda obs: np.zeros(n_actions)


@pytest.mark.parametrize("env_id", ["Humanoid-v5", "Hopper-v5"])
@pytest.mark.parametrize("make_policy", [_random_policy, _frozen_policy])
def test_a_policy_that_only_falls_keeps_no_more_contested_matches_than_chance(
    env_id: str, make_policy: Callable[[int], Policy]
) -> None:
    # Five standing-teacher brackets; a contested match is won by the lower stored R. A policy
    # that ignores the advice keeps each with probability at most 1/2, so its kept count must
    # stay at or below the binomial(n, 1/2) 99th percentile (one-sided, 1% false alarm). Without
    # the burn-in (burn_in=0) the random Humanoid policy keeps 32 of 39, above that bound 27.
    docs = [
        run_tournament(env_id=env_id, n_candidates=16, p=0.9, seed=s, teacher="standing")
        for s in range(5)
    ]
    n_actions = make_env(env_id).action_space.shape[0]
    visited = visited_states(make_policy(n_actions), env_id, RolloutOptions(episodes=10))
    n = kept = 0
    for doc in docs:
        scores = occupancy_scores(visited, doc)
        reward = {c.id: c.env_reward for c in doc.candidates}
        for m, winner in doc.matches:
            if score_winner(reward, m.a, m.b) not in (None, winner):
                n += 1
                kept += score_winner(scores, m.a, m.b) == winner
    assert n >= 20
    assert kept <= binom.ppf(0.99, n, 0.5)


def _candidate(i: int) -> Candidate:
    return Candidate(i, np.zeros(2), np.zeros(2), 0.0)


@pytest.mark.parametrize(
    "sa, sb, expected",
    [(1.0, 0.0, 0), (0.0, 1.0, 1), (0.5, 0.5, None), (-2.0, -2.0, None)],
)
def test_one_tie_rule_for_scores_and_the_score_judge(
    sa: float, sb: float, expected: int | None
) -> None:
    scores = {0: sa, 1: sb}
    assert score_winner(scores, 0, 1) == expected
    # a tie has no preference; the bracket still advances a, the higher seed's side
    assert ScoreJudge(scores)(_candidate(0), _candidate(1)) == (0 if expected is None else expected)
    assert score_winner(scores, 1, 0) == expected
