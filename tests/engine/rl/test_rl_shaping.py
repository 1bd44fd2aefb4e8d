"""Advice shaping wrappers and exact env snapshots."""

from __future__ import annotations

import numpy as np
import pytest

from engine.envs import make_env
from engine.rl.shaping import reached_qpos
from engine.rl.vecenv import make_vec_env, restore_vec, snapshot_vec


def test_reached_qpos_of_a_finished_env_comes_from_final_info() -> None:
    info = {
        "qpos": np.array([[0.0, 0.0], [1.0, 1.0]]),
        "final_info": {"qpos": np.array([[0.0, 0.0], [9.0, 9.0]])},
    }
    out = reached_qpos(info, np.array([False, True]))
    np.testing.assert_array_equal(out, [[0.0, 0.0], [9.0, 9.0]])
    assert info["qpos"][1, 0] == 1.0  # the caller's info is not modified


@pytest.mark.parametrize("offset", [0.0, 2.0])
def test_advice_term_is_scaled_f_of_the_reached_state(offset: float) -> None:
    """Against single envs stepped alongside: F of the state each step reached, read before
    any reset (so a finished episode's term is its last state, not the next one's first),
    plus the offset, times the scale."""
    envs = make_vec_env(
        "InvertedPendulum-v5", 3, lambda q: q[:, 1] * 10.0, advice_scale=0.5, advice_offset=offset
    )
    envs.reset(seed=0)
    refs = [make_env("InvertedPendulum-v5") for _ in range(3)]
    for i, ref in enumerate(refs):
        ref.reset(seed=i)  # the vector env seeds sub-env i with seed + i
    finished = 0
    for _ in range(40):  # long enough for some episodes to end and autoreset
        _, reward, _, _, info = envs.step(np.full((3, 1), 3.0))
        for i, ref in enumerate(refs):
            _, ref_reward, ref_term, ref_trunc, _ = ref.step(np.array([3.0]))
            assert info["advice"][i] == 0.5 * (10.0 * ref.unwrapped.data.qpos[1] + offset)
            assert info["env_reward"][i] == reward[i] == ref_reward
            if ref_term or ref_trunc:
                finished += 1
                ref.reset()  # like the vector env's autoreset: the env's own generator
    assert finished >= 3
    envs.close()


@pytest.mark.parametrize("env_id", ["InvertedPendulum-v5", "Hopper-v5"])
def test_snapshot_restores_the_exact_future(env_id: str) -> None:
    rng = np.random.default_rng(0)
    a = make_vec_env(env_id, 2, None)
    a.reset(seed=0)
    actions = rng.uniform(-1, 1, size=(60, 2, a.single_action_space.shape[0]))
    for act in actions[:20]:
        a.step(act)
    snap = snapshot_vec(a)
    future = [a.step(act)[:4] for act in actions[20:]]
    b = make_vec_env(env_id, 2, None)
    b.reset(seed=123)
    restore_vec(b, snap)
    for act, expected in zip(actions[20:], future, strict=True):
        for got, want in zip(b.step(act)[:4], expected, strict=True):
            np.testing.assert_array_equal(got, want)
