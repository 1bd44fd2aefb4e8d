"""The training vector env, and exact snapshots of its sub-envs for resumable checkpoints."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import torch

from engine.envs import make_env
from engine.rl.shaping import AdviceFn, AdviceShaping, StateInfo

_FULL_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def make_vec_env(env_id: str, n_envs: int, advice: AdviceFn | None,
                 advice_scale: float = 1.0) -> AdviceShaping:
    """``n_envs`` copies of ``env_id`` in a ``SyncVectorEnv`` with same-step autoreset.

    On two cores the synchronous env beats ``AsyncVectorEnv``: the learner and the simulator
    alternate, so worker processes only add pickling and IPC.

    Raises:
        InputError: ``env_id`` is not a Gymnasium MuJoCo env.
    """
    def thunk() -> gym.Env:
        return StateInfo(make_env(env_id, disable_env_checker=True))

    vec = gym.vector.SyncVectorEnv([thunk] * n_envs,
                                   autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    return AdviceShaping(vec, advice, advice_scale)


def _time_limit(env: gym.Env) -> gym.wrappers.TimeLimit | None:
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            return env
        env = env.env
    return None


def snapshot_env(env: gym.Env) -> dict[str, Any]:
    """Everything that decides a sub-env's future: full MuJoCo state, step count, rng state."""
    base = env.unwrapped
    state = np.empty(mujoco.mj_stateSize(base.model, _FULL_STATE))
    mujoco.mj_getState(base.model, base.data, state, _FULL_STATE)
    limit = _time_limit(env)
    return {"mujoco": torch.from_numpy(state),
            "elapsed_steps": None if limit is None else limit._elapsed_steps,
            "np_random": base.np_random.bit_generator.state}


def restore_env(env: gym.Env, snap: dict[str, Any]) -> None:
    """Inverse of :func:`snapshot_env` (``env`` must have been reset once)."""
    base = env.unwrapped
    mujoco.mj_setState(base.model, base.data, snap["mujoco"].numpy(), _FULL_STATE)
    # Derived quantities (body positions, ...) are read by some envs before their next step.
    mujoco.mj_forward(base.model, base.data)
    limit = _time_limit(env)
    if limit is not None:
        limit._elapsed_steps = snap["elapsed_steps"]
    base.np_random.bit_generator.state = snap["np_random"]


def snapshot_vec(envs: AdviceShaping) -> list[dict[str, Any]]:
    """Snapshots of all sub-envs of a :func:`make_vec_env` env."""
    return [snapshot_env(env) for env in envs.unwrapped.envs]


def restore_vec(envs: AdviceShaping, snaps: list[dict[str, Any]]) -> None:
    """Restore the sub-envs saved by :func:`snapshot_vec`."""
    for env, snap in zip(envs.unwrapped.envs, snaps, strict=True):
        restore_env(env, snap)
