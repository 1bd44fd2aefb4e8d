"""Gymnasium MuJoCo environments: creation, state snapshots and restoring a stored state.

A *state* is what we need to restore and render a moment of an episode: ``qpos`` and ``qvel``.
Everything else (observation, reward terms) is derived from them by :func:`restore`;
:func:`snapshot` captures all of it as a :class:`StateSnapshot`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.rewards import reward_terms, total_reward

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco

DEFAULT_ENV_ID = "Humanoid-v5"


def make_env(env_id: str = DEFAULT_ENV_ID, **kwargs: Any) -> gym.Env[Any, Any]:
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
        raise InputError(
            f"unknown env {env_id!r}: expected a Gymnasium MuJoCo id such as "
            f"{DEFAULT_ENV_ID!r} or 'Hopper-v5'"
        )
    try:
        env = gym.make(env_id)
    except Exception as exc:  # a missing extra (box2d, ...), a broken entry point
        raise InputError(
            f"cannot make env {env_id!r}: {type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else 'no details'}"
        ) from exc
    try:
        if not hasattr(env.unwrapped, "set_state") or not hasattr(env.unwrapped, "data"):
            raise InputError(f"env {env_id!r} is not a MuJoCo env (no qpos/qvel state)")
    finally:
        env.close()


def restore(env: gym.Env[Any, Any], qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """Put ``env`` into the state ``(qpos, qvel)`` and return its observation there.

    ``set_state`` runs ``mj_forward``, so positions, contacts and sensors are current. We also
    compute the quantities MuJoCo leaves lazy (external contact forces, subtree velocities) so
    that reward terms read from ``data`` are those of this state.
    """
    base = mujoco_base(env)
    qpos, qvel = np.asarray(qpos, dtype=np.float64), np.asarray(qvel, dtype=np.float64)
    if qpos.shape != (base.model.nq,) or qvel.shape != (base.model.nv,):
        raise InputError(
            f"state shape mismatch: env {env.spec.id if env.spec else '?'} wants "
            f"qpos ({base.model.nq},) and qvel ({base.model.nv},), got "
            f"{qpos.shape} and {qvel.shape}"
        )
    base.set_state(qpos, qvel)
    import mujoco

    mujoco.mj_rnePostConstraint(base.model, base.data)
    mujoco.mj_subtreeVel(base.model, base.data)
    return np.asarray(base._get_obs(), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class StateSnapshot:
    """A stored state and what the env derives from it.

    Attributes:
        qpos: generalised positions, shape ``(nq,)``.
        qvel: generalised velocities, shape ``(nv,)``.
        observation: the env's observation in this state, as :func:`restore` returns it in a
            freshly reset env.
        reward_terms: the named terms of R(s) (:func:`engine.rewards.reward_terms`).
    """

    qpos: np.ndarray
    qvel: np.ndarray
    observation: np.ndarray
    reward_terms: dict[str, float]

    @property
    def reward(self) -> float:
        """R(s), the sum of the reward terms."""
        return total_reward(self.reward_terms)


def snapshot(env: gym.Env[Any, Any]) -> StateSnapshot:
    """Capture the env's current state; :func:`restore` of its qpos/qvel gives it back.

    Observation and reward terms are computed on scratch MuJoCo data holding only
    ``(qpos, qvel)``, with zero control and solver warm start, as in a freshly reset env.
    Humanoid's contact forces (in its observation and contact cost) depend on both, so this
    makes the snapshot a function of the state alone, the same whichever env or rollout it
    comes from; the env itself is left untouched, so it may be taken in the middle of a rollout.
    """
    base = mujoco_base(env)
    live = base.data
    qpos, qvel = live.qpos.copy(), live.qvel.copy()
    import mujoco

    base.data = mujoco.MjData(base.model)  # the env's methods read `data`: point them here
    try:
        observation = restore(env, qpos, qvel)
        terms = reward_terms(env)
    finally:
        base.data = live
    return StateSnapshot(qpos, qvel, observation, terms)


@lru_cache(maxsize=16)
def env_model(env_id: str) -> mujoco.MjModel:
    """The MuJoCo model of ``env_id`` (cached; treat as read-only)."""
    env = make_env(env_id)
    try:
        return mujoco_base(env).model
    finally:
        env.close()


@lru_cache(maxsize=64)
def env_dims(env_id: str) -> tuple[int, int]:
    """The observation and action sizes of ``env_id``: what a policy from elsewhere must read
    and write (:mod:`engine.policies`). Shapes alone do not tell envs apart (Humanoid-v5 and
    HumanoidStandup-v5 share both), so the env id is checked as well."""
    env = make_env(env_id)
    try:
        obs, act = box(env.observation_space).shape, box(env.action_space).shape
    finally:
        env.close()
    return int(np.prod(obs)), int(np.prod(act))
