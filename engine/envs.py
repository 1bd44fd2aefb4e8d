"""Gymnasium MuJoCo environments: creation, state snapshots and restoring a stored state.

A *state* is what we need to restore and render a moment of an episode: ``qpos`` and ``qvel``.
Everything else (observation, reward terms) is derived from them by :func:`restore`.
"""

from __future__ import annotations

from functools import lru_cache

import gymnasium as gym
import mujoco
import numpy as np

from engine.errors import InputError

DEFAULT_ENV_ID = "Humanoid-v5"


def make_env(env_id: str = DEFAULT_ENV_ID, **kwargs) -> gym.Env:
    """Make a Gymnasium MuJoCo env, failing with a clear message for anything else.

    Args:
        env_id: a registered Gymnasium id whose unwrapped env is a ``MujocoEnv``.
        **kwargs: passed to :func:`gymnasium.make` (for example ``render_mode``).

    Raises:
        InputError: the id is unknown, or the env is not a MuJoCo env with ``qpos``/``qvel``.
    """
    check_env_id(env_id)
    return gym.make(env_id, **kwargs)


@lru_cache(maxsize=64)
def check_env_id(env_id: str) -> None:
    """Raise :class:`InputError` unless ``env_id`` names a Gymnasium MuJoCo env."""
    if env_id not in gym.registry:
        raise InputError(f"unknown env {env_id!r}: expected a Gymnasium MuJoCo id such as "
                         f"{DEFAULT_ENV_ID!r} or 'Hopper-v5'")
    env = gym.make(env_id)
    try:
        if not hasattr(env.unwrapped, "set_state") or not hasattr(env.unwrapped, "data"):
            raise InputError(f"env {env_id!r} is not a MuJoCo env (no qpos/qvel state)")
    finally:
        env.close()


def restore(env: gym.Env, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """Put ``env`` into the state ``(qpos, qvel)`` and return its observation there.

    ``set_state`` runs ``mj_forward``, so positions, contacts and sensors are current. We also
    compute the quantities MuJoCo leaves lazy (external contact forces, subtree velocities) so
    that reward terms read from ``data`` are those of this state.
    """
    base = env.unwrapped
    qpos, qvel = np.asarray(qpos, dtype=np.float64), np.asarray(qvel, dtype=np.float64)
    if qpos.shape != (base.model.nq,) or qvel.shape != (base.model.nv,):
        raise InputError(f"state shape mismatch: env {env.spec.id if env.spec else '?'} wants "
                         f"qpos ({base.model.nq},) and qvel ({base.model.nv},), got "
                         f"{qpos.shape} and {qvel.shape}")
    base.set_state(qpos, qvel)
    mujoco.mj_rnePostConstraint(base.model, base.data)
    mujoco.mj_subtreeVel(base.model, base.data)
    return np.asarray(base._get_obs(), dtype=np.float64)


@lru_cache(maxsize=16)
def env_model(env_id: str) -> mujoco.MjModel:
    """The MuJoCo model of ``env_id`` (cached; treat as read-only)."""
    env = make_env(env_id)
    try:
        return env.unwrapped.model
    finally:
        env.close()
