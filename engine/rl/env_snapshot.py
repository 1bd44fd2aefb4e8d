"""A sub-env's exact state as numpy arrays, and its restore.

A snapshot holds the env's MuJoCo data arrays, its time, the ``TimeLimit``'s step count and its
generator state: what a checkpoint needs so that a resumed run steps on with the same numbers.
The learner snapshots its own envs here (:mod:`engine.rl.vecenv` keeps the arrays as tensors),
the env helper process its envs (:mod:`engine.rl.envproc`, which sends them as numpy).

This module imports no torch: the helper process imports it.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from engine.gym_types import mujoco_base


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


def snapshot_arrays(env: gym.Env[Any, Any]) -> dict[str, Any]:
    """:func:`engine.rl.vecenv.snapshot_env` with numpy arrays (what the helper sends)."""
    base = mujoco_base(env)
    limit = _time_limit(env)
    return {
        "mujoco": {k: v.copy() for k, v in _data_arrays(base.data).items()},
        "time": float(base.data.time),
        "elapsed_steps": None if limit is None else limit._elapsed_steps,
        "np_random": base.np_random.bit_generator.state,
    }


def restore_arrays(env: gym.Env[Any, Any], snap: dict[str, Any]) -> None:
    """Inverse of :func:`snapshot_arrays`; its arrays may be numpy arrays or CPU tensors."""
    base = mujoco_base(env)
    for name, array in _data_arrays(base.data).items():
        saved = np.asarray(snap["mujoco"][name])
        # per-constraint buffers (efc_*) change size every step and are rebuilt by mj_step
        if saved.shape == array.shape:
            array[...] = saved
    base.data.time = snap["time"]
    limit = _time_limit(env)
    if limit is not None:
        limit._elapsed_steps = snap["elapsed_steps"]
    base.np_random.bit_generator.state = snap["np_random"]
