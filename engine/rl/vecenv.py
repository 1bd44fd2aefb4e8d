"""The training vector env, and exact snapshots of its sub-envs for resumable checkpoints."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import mujoco
import numpy as np
import torch

from engine.envs import make_env
from engine.gym_types import mujoco_base
from engine.rl.shaping import AdviceFn, AdviceShaping, StateInfo

if TYPE_CHECKING:
    from gymnasium.vector import SyncVectorEnv


def make_vec_env(
    env_id: str,
    n_envs: int,
    advice: AdviceFn | None,
    advice_scale: float = 1.0,
    advice_offset: float = 0.0,
) -> AdviceShaping:
    """``n_envs`` copies of ``env_id`` in a ``SyncVectorEnv`` with same-step autoreset.

    On two cores the synchronous env beats ``AsyncVectorEnv``: the learner and the simulator
    alternate, so worker processes only add pickling and IPC.

    Raises:
        InputError: ``env_id`` is not a Gymnasium MuJoCo env.
    """

    def thunk() -> gym.Env[Any, Any]:
        return StateInfo(make_env(env_id, disable_env_checker=True))

    vec = gym.vector.SyncVectorEnv(
        [thunk] * n_envs, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP
    )
    return AdviceShaping(vec, advice, advice_scale, advice_offset)


def _time_limit(env: gym.Env[Any, Any]) -> gym.wrappers.TimeLimit[Any, Any] | None:
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            return env
        env = env.env
    return None


def _data_arrays(data: mujoco.MjData) -> dict[str, np.ndarray]:
    return {
        name: value
        for name in dir(data)
        if not name.startswith("_") and isinstance(value := getattr(data, name), np.ndarray)
    }


def snapshot_env(env: gym.Env[Any, Any]) -> dict[str, Any]:
    """Everything that decides a sub-env's future: MuJoCo data, step count, rng state.

    We copy every array of ``MjData``, not only the integration state: Gymnasium envs read
    quantities left over from the previous ``mj_step`` (Humanoid's centre of mass uses the
    pre-integration ``xipos``), and recomputing them with ``mj_forward`` would change rewards.
    """
    base = mujoco_base(env)
    limit = _time_limit(env)
    return {
        "mujoco": {k: torch.from_numpy(v.copy()) for k, v in _data_arrays(base.data).items()},
        "time": float(base.data.time),
        "elapsed_steps": None if limit is None else limit._elapsed_steps,
        "np_random": base.np_random.bit_generator.state,
    }


def restore_env(env: gym.Env[Any, Any], snap: dict[str, Any]) -> None:
    """Inverse of :func:`snapshot_env` (``env`` must have been reset once)."""
    base = mujoco_base(env)
    for name, array in _data_arrays(base.data).items():
        saved = snap["mujoco"][name]
        # per-constraint buffers (efc_*) change size every step and are rebuilt by mj_step
        if tuple(saved.shape) == array.shape:
            array[...] = saved.numpy()
    base.data.time = snap["time"]
    limit = _time_limit(env)
    if limit is not None:
        limit._elapsed_steps = snap["elapsed_steps"]
    base.np_random.bit_generator.state = snap["np_random"]


def snapshot_vec(envs: AdviceShaping) -> list[dict[str, Any]]:
    """Snapshots of all sub-envs of a :func:`make_vec_env` env."""
    return [snapshot_env(env) for env in _sub_envs(envs)]


def restore_vec(envs: AdviceShaping, snaps: list[dict[str, Any]]) -> None:
    """Restore the sub-envs saved by :func:`snapshot_vec`."""
    for env, snap in zip(_sub_envs(envs), snaps, strict=True):
        restore_env(env, snap)


def _sub_envs(envs: AdviceShaping) -> list[gym.Env[Any, Any]]:
    """The sub-envs of a :func:`make_vec_env` env (its unwrapped env is a ``SyncVectorEnv``)."""
    return cast("SyncVectorEnv[Any, Any]", envs.unwrapped).envs
