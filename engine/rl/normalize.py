"""Running observation normalisation and return-based reward scaling (CleanRL, SB3).

Both keep their statistics in :class:`gymnasium.wrappers.utils.RunningMeanStd` and are shared
by all envs of a vector env, so one normaliser travels in a checkpoint and can be applied to
states that never came from a rollout (the agent preference tree).
"""

from __future__ import annotations

from typing import SupportsFloat, cast

import numpy as np
from gymnasium.wrappers.utils import RunningMeanStd

#: Added to the variance before its square root (SB3's ``VecNormalize`` default): an imported
#: policy's normalisation (:mod:`engine.policies.normalisation`) names it, ACV's is this one.
OBS_EPSILON = 1e-8


class ObsNormalizer:
    """``clip((obs - mean) / std, -clip, clip)`` with running mean and std over all seen obs.

    Args:
        shape: observation shape, e.g. ``(348,)`` for Humanoid-v5.
        clip: absolute bound of a normalised value.
        enabled: when False, :meth:`__call__` returns the observations unchanged.
    """

    def __init__(self, shape: tuple[int, ...], clip: float = 10.0, enabled: bool = True):
        self.rms = RunningMeanStd(shape=shape)
        self.clip = clip
        self.enabled = enabled

    def update(self, obs: np.ndarray) -> None:
        """Add a batch of observations, shape (B, *shape), to the statistics."""
        if self.enabled:
            self.rms.update(obs)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Normalised float32 observations, same shape as ``obs``."""
        if not self.enabled:
            return np.asarray(obs, dtype=np.float32)
        out = (obs - self.rms.mean) / np.sqrt(self.rms.var + OBS_EPSILON)
        return np.clip(out, -self.clip, self.clip).astype(np.float32)

    def state_dict(self) -> dict[str, object]:
        """Statistics as plain values (checkpoint friendly)."""
        return {
            "mean": self.rms.mean.tolist(),
            "var": self.rms.var.tolist(),
            "count": float(self.rms.count),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the statistics saved by :meth:`state_dict`."""
        self.rms.mean = np.asarray(state["mean"], dtype=np.float64)
        self.rms.var = np.asarray(state["var"], dtype=np.float64)
        self.rms.count = float(cast(SupportsFloat, state["count"]))


class RewardScaler:
    """Divide rewards by the running std of the discounted return (no mean subtraction).

    The same scale is applied to the env reward and to the advice F, so that z keeps its
    meaning: the shaped reward is ``(R + z F) / std``.

    Args:
        n_envs: number of envs whose discounted returns are tracked.
        gamma: discount of the tracked return.
        clip: absolute bound of a scaled reward.
        enabled: when False, the scale is 1.
    """

    def __init__(self, n_envs: int, gamma: float, clip: float = 10.0, enabled: bool = True):
        self.rms = RunningMeanStd(shape=())
        self.returns = np.zeros(n_envs)
        self.gamma = gamma
        self.clip = clip
        self.enabled = enabled

    def update(self, rewards: np.ndarray, dones: np.ndarray) -> None:
        """Track the discounted return of each env; ``dones`` ends the return after this step."""
        if not self.enabled:
            return
        self.returns = self.returns * self.gamma + rewards
        self.rms.update(self.returns)
        self.returns[dones] = 0.0

    def __call__(self, rewards: np.ndarray) -> np.ndarray:
        """Scaled and clipped rewards, same shape as ``rewards``."""
        if not self.enabled:
            return rewards
        return np.clip(rewards / np.sqrt(self.rms.var + 1e-8), -self.clip, self.clip)

    def state_dict(self) -> dict[str, object]:
        """Statistics and per-env returns as plain values."""
        return {
            "var": float(self.rms.var),
            "mean": float(self.rms.mean),
            "count": float(self.rms.count),
            "returns": self.returns.tolist(),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state saved by :meth:`state_dict`."""
        # gymnasium infers ndarray for these; with shape () a float64 scalar is what it keeps
        self.rms.mean = np.float64(cast(SupportsFloat, state["mean"]))  # type: ignore[assignment]
        self.rms.var = np.float64(cast(SupportsFloat, state["var"]))  # type: ignore[assignment]
        self.rms.count = float(cast(SupportsFloat, state["count"]))
        self.returns = np.asarray(state["returns"], dtype=np.float64)
