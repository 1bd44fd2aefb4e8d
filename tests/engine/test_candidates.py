"""Envs, state snapshots, the state reward R(s) and candidate sampling."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from engine.candidates import sample_candidates
from engine.envs import check_env_id, env_model, make_env, restore, snapshot
from engine.errors import InputError
from engine.rewards import posture_features, state_reward
from engine.teachers import standing_score


@pytest.mark.parametrize("env_id", ["Humanoid-v5", "Hopper-v5"])
@pytest.mark.parametrize("mode", ["uniform", "diverse"])
def test_sampling_is_seeded_and_complete(env_id: str, mode: str) -> None:
    first = sample_candidates(env_id, 8, rng=np.random.default_rng(0), mode=mode)
    again = sample_candidates(env_id, 8, rng=np.random.default_rng(0), mode=mode)
    assert [c.id for c in first] == list(range(8))
    model = env_model(env_id)
    assert all(c.qpos.shape == (model.nq,) and c.qvel.shape == (model.nv,) for c in first)
    assert all(
        np.array_equal(a.qpos, b.qpos) and a.env_reward == b.env_reward
        for a, b in zip(first, again, strict=True)
    )
    assert len({c.qpos.tobytes() for c in first}) == 8


@pytest.mark.parametrize("env_id", ["Humanoid-v5", "Hopper-v5"])
def test_restore_round_trips_state_and_reward(env_id: str) -> None:
    cand = sample_candidates(env_id, 3, rng=np.random.default_rng(1))[2]
    env = make_env(env_id)
    env.reset(seed=0)
    obs = restore(env, cand.qpos, cand.qvel)
    assert np.allclose(env.unwrapped.data.qpos, cand.qpos)
    assert obs.shape == env.observation_space.shape
    assert state_reward(env) == pytest.approx(cand.env_reward)
    env.close()


def test_humanoid_reward_terms_match_a_real_step() -> None:
    """R(s) of a visited state equals the env's own healthy and contact terms there."""
    env = make_env("Humanoid-v5")
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(env.action_space.shape))
    base = env.unwrapped
    restore(env, base.data.qpos.copy(), base.data.qvel.copy())
    forward = state_reward(env) - info["reward_survive"] - info["reward_contact"]
    # The env's forward term is a finite difference over the step; ours is instantaneous.
    assert forward == pytest.approx(info["reward_forward"], abs=0.1)
    env.close()


def test_diverse_sampling_spreads_postures() -> None:
    model = env_model("Humanoid-v5")
    spread = {}
    for mode in ("uniform", "diverse"):
        cands = sample_candidates("Humanoid-v5", 12, rng=np.random.default_rng(2), mode=mode)
        feats = posture_features(np.stack([c.qpos for c in cands]), model)
        spread[mode] = feats.std(0).sum()
    assert spread["diverse"] > spread["uniform"]


def test_standing_prefers_the_initial_pose_over_a_fallen_one() -> None:
    model = env_model("Humanoid-v5")
    standing = model.qpos0.copy()
    fallen = model.qpos0.copy()
    fallen[2] = 0.3
    fallen[3:7] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]  # lying on its side
    scores = standing_score(np.stack([standing, fallen]), model)
    assert scores[0] == pytest.approx(1.0) and scores[1] < 0.01


@pytest.mark.parametrize(
    ("env_id", "n"), [("Foo-v9", 4), ("CartPole-v1", 4), ("Hopper-v5", 1), ("Hopper-v5", 129)]
)
def test_bad_sampling_arguments(env_id: str, n: int) -> None:
    with pytest.raises(InputError):
        sample_candidates(env_id, n, rng=np.random.default_rng(0))


@pytest.mark.parametrize("env_id", ["Humanoid-v5", "Hopper-v5"])
def test_snapshot_restores_into_a_fresh_env(env_id: str) -> None:
    env, fresh = make_env(env_id), make_env(env_id)
    env.reset(seed=3)
    env.action_space.seed(3)
    for _ in range(15):  # mid-episode: non-zero control, warm-started contact solver
        env.step(env.action_space.sample())
    snap = snapshot(env)
    np.testing.assert_array_equal(snap.qpos, env.unwrapped.data.qpos)
    assert set(snap.reward_terms) == {"healthy", "forward", "contact_cost", "control_cost"}
    fresh.reset(seed=99)
    np.testing.assert_array_equal(restore(fresh, snap.qpos, snap.qvel), snap.observation)
    assert snap.reward == state_reward(fresh)
    assert snapshot(fresh).reward_terms == snap.reward_terms
    env.close()
    fresh.close()


def test_snapshot_leaves_the_env_untouched() -> None:
    env = make_env("Humanoid-v5")
    env.reset(seed=0)
    env.step(np.full(env.action_space.shape, 0.3))
    data = env.unwrapped.data
    before = {name: getattr(data, name).copy() for name in ("qpos", "ctrl", "cfrc_ext", "xipos")}
    snap = snapshot(env)
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(data, name), value)
    env.step(np.zeros(env.action_space.shape))
    assert not np.array_equal(snap.qpos, data.qpos)  # a copy, not a view of the live state
    env.close()


def _needs_box2d(**kwargs):
    raise gym.error.DependencyNotInstalled("Box2D is not installed")


def test_env_that_cannot_be_made_is_an_input_error() -> None:
    gym.register(id="AcvBroken-v0", entry_point=_needs_box2d)
    try:
        with pytest.raises(InputError, match="AcvBroken-v0.*DependencyNotInstalled.*Box2D"):
            check_env_id("AcvBroken-v0")
        with pytest.raises(InputError, match="AcvBroken-v0"):
            sample_candidates("AcvBroken-v0", 4, rng=np.random.default_rng(0))
    finally:
        del gym.registry["AcvBroken-v0"]
