"""The ``informative`` sampling mode: a no-advice baseline's return estimate, spread over its
range, diverse in posture, and seeding the bracket high against low (issue 25 §5)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.bracket import make_first_round
from engine.candidates import Candidate, sample_candidates, seed_abilities
from engine.errors import InputError
from engine.informative import (
    CANDIDATE_SEED_LOW,
    informative_pool,
    pick_informative,
    sample_informative,
)
from engine.pipeline import sample_by_mode


def _hold_joints(obs: np.ndarray) -> np.ndarray:
    """A tiny hand-written Hopper policy: push each joint back toward straight."""
    return np.asarray(-np.clip(obs[2:5], -1.0, 1.0))


def _sample(seed: int, n: int = 4) -> list[Candidate]:
    return sample_informative(
        "Hopper-v5", n, rng=np.random.default_rng(seed), rollout_steps=100, policy=_hold_joints
    )


def test_informative_gives_n_distinct_reproducible_candidates_with_scores() -> None:
    first, again = _sample(0), _sample(0)
    assert [c.id for c in first] == [0, 1, 2, 3]
    assert len({c.qpos.tobytes() for c in first}) == 4
    assert all(c.seed_score is not None and np.isfinite(c.seed_score) for c in first)
    for a, b in zip(first, again, strict=True):
        assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.qvel, b.qvel)
        assert a.seed_score == b.seed_score and a.env_reward == b.env_reward
    assert not all(np.array_equal(a.qpos, b.qpos) for a, b in zip(first, _sample(1), strict=True))


def test_informative_spreads_the_estimate_over_the_pools_range() -> None:
    """The candidates reach the pool's lowest and highest stratum (one N-th of its range)."""
    n = 4
    pool = informative_pool("Hopper-v5", n, 100, np.random.default_rng(0), _hold_joints)
    scores = np.array([c.seed_score for c in _sample(0, n)], dtype=np.float64)
    width = np.ptp(pool.estimate) / n
    assert width > 0
    assert scores.min() <= pool.estimate.min() + width
    assert scores.max() >= pool.estimate.max() - width
    assert set(scores) <= set(pool.estimate)
    assert pool.from_baseline.any() and (~pool.from_baseline).any()


def test_informative_needs_a_baseline_policy() -> None:
    with pytest.raises(InputError, match="informative sampling needs a trained no-advice"):
        sample_by_mode("Hopper-v5", 4, rng=np.random.default_rng(0), mode="informative")


def test_sampling_by_mode_is_the_pure_sampler_or_the_informative_one() -> None:
    """The pipeline's entry point draws exactly what each sampler draws; the pure sampler
    (below the agents) refuses ``informative`` and says where it is."""
    informative = sample_by_mode(
        "Hopper-v5",
        4,
        rng=np.random.default_rng(0),
        mode="informative",
        rollout_steps=100,
        policy=_hold_joints,
    )
    uniform = sample_by_mode("Hopper-v5", 4, rng=np.random.default_rng(0), rollout_steps=100)
    pure = sample_candidates("Hopper-v5", 4, rng=np.random.default_rng(0), rollout_steps=100)
    for got, expected in ((informative, _sample(0)), (uniform, pure)):
        assert [(c.qpos.tobytes(), c.seed_score) for c in got] == [
            (c.qpos.tobytes(), c.seed_score) for c in expected
        ]
    with pytest.raises(InputError, match="sample_by_mode samples in every mode"):
        sample_candidates(
            "Hopper-v5",
            4,
            rng=np.random.default_rng(0),
            mode="informative",  # type: ignore[arg-type]
            policy=_hold_joints,
        )


def test_pick_takes_one_state_per_stratum_far_apart_in_posture() -> None:
    """Two states per stratum, one near the others' posture and one far: the far one wins
    every stratum but the first one visited (drawn at random)."""
    n = 5
    estimate = np.repeat(np.arange(n, dtype=np.float64), 2)  # strata 0..4, two states each
    features = np.zeros((2 * n, 2))
    features[1::2] = [[10.0, 0.0], [0.0, 10.0], [-10.0, 0.0], [0.0, -10.0], [7.0, 7.0]]
    picked = pick_informative(estimate, features, n, np.random.default_rng(3))
    assert list(estimate[picked]) == list(range(n))  # one per stratum, lowest first
    assert sum(i % 2 == 1 for i in picked) >= n - 1
    again = pick_informative(estimate, features, n, np.random.default_rng(3))
    assert np.array_equal(picked, again)


def test_pick_fills_empty_strata_and_handles_a_flat_estimate() -> None:
    rng = np.random.default_rng(0)
    features = rng.normal(size=(12, 3))
    skewed = np.array([0.0] * 10 + [9.0, 10.0])  # strata 1..n-2 are empty
    picked = pick_informative(skewed, features, 6, rng)
    assert len(set(picked.tolist())) == 6 and {10, 11} <= set(picked.tolist())
    flat = pick_informative(np.zeros(12), features, 6, rng)
    assert len(set(flat.tolist())) == 6


def test_seed_scores_seed_the_bracket_high_against_low() -> None:
    """At p = 0 seed k meets seed N + 1 - k: every first-round match crosses the median."""
    n = 8
    scores = np.random.default_rng(5).permutation(n).astype(np.float64) * 10.0
    cands = [Candidate(i, np.zeros(3), np.zeros(3), -scores[i], float(scores[i])) for i in range(n)]
    abilities = seed_abilities(cands)
    assert np.array_equal(abilities, scores)  # the seed score, not R(s)
    first_round = make_first_round(list(range(n)), abilities, 0.0, np.random.default_rng(0))
    median = np.median(scores)
    ranks = {int(i): r for r, i in enumerate(np.argsort(-scores), start=1)}
    for a, b in first_round:
        assert b is not None
        assert (scores[a] > median) != (scores[b] > median)
        assert ranks[a] + ranks[b] == n + 1
    plain = [Candidate(i, np.zeros(3), np.zeros(3), float(i)) for i in range(3)]
    assert np.array_equal(seed_abilities(plain), [0.0, 1.0, 2.0])  # R(s) without a seed score


def test_candidate_rollouts_reset_above_the_evaluation_seeds() -> None:
    """The judges reset with small seeds (option seed + episode); candidate rollouts never do."""
    from engine.rl.behaviour import RolloutOptions
    from engine.rl.returns import ReturnOptions

    behaviour, returns = RolloutOptions(), ReturnOptions()
    assert behaviour.seed + behaviour.episodes < CANDIDATE_SEED_LOW
    assert returns.seed < CANDIDATE_SEED_LOW
