"""Static types for the parts of Gymnasium's MuJoCo envs that the engine reads.

Gymnasium types ``env.unwrapped`` as a plain ``Env`` and every space as ``Space``, and MuJoCo
ships no type information. These helpers narrow them for the type checker only: each is a
``typing.cast``, with no effect at run time (nothing here imports MuJoCo, so importing this
module never chooses a GL backend before :mod:`engine.mujoco_gl` has checked ``MUJOCO_GL``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    import gymnasium as gym
    import mujoco
    from gymnasium.spaces import Box


class MujocoBase(Protocol):
    """What the engine uses of an unwrapped Gymnasium ``MujocoEnv`` (and its subclasses).

    ``MujocoEnv.set_state`` is unannotated upstream and ``_get_obs`` is defined by each
    subclass (Humanoid, Hopper, ...), so this protocol, not ``MujocoEnv`` itself, is the type.
    """

    model: mujoco.MjModel
    data: mujoco.MjData

    @property
    def np_random(self) -> np.random.Generator: ...

    def set_state(self, qpos: NDArray[np.float64], qvel: NDArray[np.float64]) -> None: ...

    def _get_obs(self) -> NDArray[np.float64]: ...


def mujoco_base(env: gym.Env[Any, Any]) -> MujocoBase:
    """``env.unwrapped``, typed as the MuJoCo env it is (see :func:`engine.envs.check_env_id`)."""
    return cast("MujocoBase", env.unwrapped)


def box(space: gym.Space[Any]) -> Box:
    """``space`` typed as the ``Box`` that MuJoCo envs' observation and action spaces are."""
    return cast("Box", space)
