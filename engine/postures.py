"""Posture targets that the environment's reward does not pay for: the `orthogonal` teacher.

The `standing` teacher agrees with the return on Humanoid (standing keeps the agent alive, so
every return-maximiser follows it), so an agent that follows it proves nothing. A posture
target the reward R does not reward, apart from the control cost of holding it, is advice
whose effect R cannot explain (issue 27):

- **Humanoid**: arms raised. The score is the mean, over both hands, of how far the hand
  sits along the torso's up axis, from its lowest reach (0) to its highest (1). It is
  measured in the torso's frame, so a fallen body with raised arms still scores high.
- **Hopper**: a bent knee, ``exp(-((q_knee - KNEE_TARGET) / KNEE_WIDTH)^2)`` of the
  ``leg_joint`` angle.

Both scores lie in [0, 1] and take a batch of ``qpos`` of shape ``(B, nq)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.errors import InputError

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco

HANDS = ("right_hand", "left_hand")  # Humanoid's hand geoms
# A hand's height along the torso's up axis, relative to the torso's origin (metres): its
# lowest and highest over the shoulders' joint ranges (measured with mj_kinematics in the
# initial pose: -0.30 and 0.34; the initial pose holds the hands at 0.06).
HAND_LOW, HAND_HIGH = -0.30, 0.34
KNEE_JOINT = "leg_joint"  # Hopper's knee, range [-2.62, 0] rad
KNEE_TARGET, KNEE_WIDTH = -0.6, 0.4  # rad: a clearly bent knee; wide enough to rank the
# nearly straight knees of random rollouts (-0.2 to 0 rad: scores 0.35 to 0.1)


def orthogonal_score(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """The `orthogonal` teacher's score of each state, in [0, 1], shape ``(B,)``.

    Raises:
        InputError: the model has neither Humanoid's hands nor Hopper's knee.
    """
    import mujoco

    q = np.atleast_2d(np.asarray(qpos, dtype=np.float64))
    if all(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, h) >= 0 for h in HANDS):
        return arms_raised(q, model)
    knee = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, KNEE_JOINT)
    if knee >= 0:
        angle = q[:, int(model.jnt_qposadr[knee])]
        return np.asarray(np.exp(-(((angle - KNEE_TARGET) / KNEE_WIDTH) ** 2)))
    raise InputError(
        "the orthogonal teacher has a posture target for Humanoid (arms raised) and Hopper "
        "(a bent knee) only"
    )


def arms_raised(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """How raised Humanoid's arms are, in [0, 1], shape ``(B,)`` (forward kinematics)."""
    import mujoco

    data = mujoco.MjData(model)
    hands = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, h) for h in HANDS]
    torso = int(model.geom_bodyid[hands[0]])
    while int(model.body_parentid[torso]) != 0:  # the hand's chain up to the root body
        torso = int(model.body_parentid[torso])
    scores = np.empty(len(qpos))
    for i, state in enumerate(qpos):
        data.qpos[:] = state
        mujoco.mj_kinematics(model, data)
        up = data.xmat[torso].reshape(3, 3)[:, 2]
        heights = [(data.geom_xpos[h] - data.xpos[torso]) @ up for h in hands]
        scores[i] = np.mean(np.clip((np.array(heights) - HAND_LOW) / (HAND_HIGH - HAND_LOW), 0, 1))
    return scores
