"""The state reward R(s) and the advice features of a state.

R(s) is the part of a Gymnasium MuJoCo locomotion reward that one state determines (docs/method.md
section 2): the healthy bonus, the forward-velocity term (centre-of-mass x velocity), the
contact cost, and the control cost only when an action is given. It is the players' *ability*
in Braverman-Mossel seeding and the `good` teacher's preference (the paper's Case 1, F = R).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from engine.gym_types import MujocoBase, mujoco_base

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco


def state_reward(env: gym.Env[Any, Any], action: np.ndarray | None = None) -> float:
    """R(s) of the env's current state; call :func:`engine.envs.restore` first.

    Args:
        env: a Gymnasium MuJoCo env (any wrapper); its ``data`` holds the state.
        action: the policy's action in this state, for the control cost; ``None`` means 0.

    Returns:
        healthy bonus + forward weight * COM x velocity - contact cost - control cost.
    """
    return total_reward(reward_terms(env, action))


def reward_terms(env: gym.Env[Any, Any], action: np.ndarray | None = None) -> dict[str, float]:
    """The named terms of R(s) in the env's current state (see :func:`state_reward`).

    Returns:
        ``healthy`` (bonus), ``forward`` (weight * COM x velocity), ``contact_cost`` and
        ``control_cost`` (0 without an action); the costs are positive numbers.
    """
    base = mujoco_base(env)
    control = 0.0 if action is None else control_cost(env, np.asarray(action))
    return {
        "healthy": float(getattr(base, "healthy_reward", 0.0)),
        "forward": float(getattr(base, "_forward_reward_weight", 1.0)) * com_x_velocity(base),
        "contact_cost": float(getattr(base, "contact_cost", 0.0)),
        "control_cost": control,
    }


def control_cost(env: gym.Env[Any, Any], action: np.ndarray) -> float:
    """The env's control cost of ``action``: ``ctrl_cost_weight * sum(action^2)``.

    Computed from the action itself: Humanoid's own ``control_cost`` reads ``data.ctrl``, the
    control last applied, which a restored state does not have.
    """
    weight = float(getattr(env.unwrapped, "_ctrl_cost_weight", 0.0))
    return weight * float(np.sum(np.square(action)))


def total_reward(terms: dict[str, float]) -> float:
    """R(s) from :func:`reward_terms` (this order of operations keeps stored values exact)."""
    return terms["healthy"] + terms["forward"] - terms["contact_cost"] - terms["control_cost"]


def com_x_velocity(base: MujocoBase) -> float:
    """Centre-of-mass x velocity of the whole model (``subtree_linvel`` of the world body)."""
    return float(base.data.subtree_linvel[0, 0])


def posture_slice(model: mujoco.MjModel) -> slice:
    """The part of ``qpos`` that describes posture, not position on the floor.

    A free-joint root (Humanoid, Ant) starts with x, y, z, quaternion: posture is ``qpos[2:]``
    (torso height, orientation, joint angles). A planar root (Hopper, Walker2d, HalfCheetah)
    starts with a slide-x joint: posture is ``qpos[1:]``.
    """
    import mujoco

    free = model.njnt > 0 and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    return slice(2, None) if free else slice(1, None)


def posture_features(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """Advice features of a batch of states.

    Args:
        qpos: shape ``(B, nq)`` or ``(nq,)``.
        model: the env's MuJoCo model.

    Returns:
        shape ``(B, nq - 2)`` for a free root, ``(B, nq - 1)`` for a planar root.
    """
    return np.atleast_2d(np.asarray(qpos, dtype=np.float64))[:, posture_slice(model)]


def uprightness(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """Cosine between the torso's up axis and the world's up axis, shape ``(B,)``.

    For a free root, ``1 - 2 (qx^2 + qy^2)`` from the torso quaternion ``(w, x, y, z)``; for a
    planar root, the cosine of the pitch angle ``qpos[2]``.
    """
    q = np.atleast_2d(np.asarray(qpos, dtype=np.float64))
    if posture_slice(model).start == 2:
        return 1.0 - 2.0 * (q[:, 4] ** 2 + q[:, 5] ** 2)
    return np.cos(q[:, 2])


def torso_height(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """Root height, shape ``(B,)``: ``qpos[2]`` for a free root, ``qpos[1]`` for a planar one."""
    q = np.atleast_2d(np.asarray(qpos, dtype=np.float64))
    return q[:, 2] if posture_slice(model).start == 2 else q[:, 1]
