"""Reward shaping with advice, as Gymnasium wrappers (paper: R~(s, a) = R(s, a) + z_phi(s) F(s)).

:class:`StateInfo` makes every sub-env report the state it reached (``qpos``) and nothing else,
which also keeps ``SyncVectorEnv``'s per-step info merging cheap. :class:`AdviceShaping`
evaluates the advice F on the whole batch of reached states at once and returns the reward
terms in ``info``; the weighting by z happens in the learner, because z_phi changes during
training.

Timing: the shaped reward of step t is ``R_t + z_phi(s_t) F(s_{t+1})``. F judges the state
the action reached, as MuJoCo's own rewards do (they are computed after the step); z_phi
weighs it at the state where the action was chosen, as in Hu et al.'s f(s, a) weighted by
z_phi(s, a). The agent preference tree evaluates both at the candidate state.
"""

from __future__ import annotations

from typing import Any, Protocol, SupportsFloat

import gymnasium as gym
import numpy as np

from engine.gym_types import mujoco_base


class AdviceFn(Protocol):
    """An advice reward: F(s) for a batch of MuJoCo positions, shape (B, nq) -> (B,).

    :class:`engine.advice.AdviceReward` is one; tests use plain functions of ``qpos``.
    """

    def __call__(self, qpos: np.ndarray) -> np.ndarray: ...


class EnvRewardAdvice:
    """F = R: the environment's own step reward as the advice (the paper's Case 1, "good
    advice"). It is no function of ``qpos``: :class:`AdviceShaping` reads the step's reward,
    and the agent's judge reads the candidate's R."""

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        raise TypeError("F = R is the step reward: AdviceShaping and the judges read it")


class StateInfo(gym.Wrapper):
    """Replace the env's ``info`` by ``{"qpos": <the state reached>}``, shape (nq,)."""

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        obs, _ = self.env.reset(**kwargs)
        return obs, {"qpos": mujoco_base(self.env).data.qpos.copy()}

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, _ = self.env.step(action)
        qpos = mujoco_base(self.env).data.qpos.copy()
        return obs, reward, terminated, truncated, {"qpos": qpos}


def reached_qpos(info: dict[str, Any], done: np.ndarray) -> np.ndarray:
    """Positions reached by the last step, shape (B, nq).

    With ``autoreset_mode=SAME_STEP`` a finished env has already been reset: its ``qpos`` is
    the new episode's first state and the reached one sits in ``info["final_info"]``.
    """
    qpos: np.ndarray = info["qpos"]
    if done.any():
        qpos = qpos.copy()
        qpos[done] = info["final_info"]["qpos"][done]
    return qpos


class AdviceShaping(gym.vector.VectorWrapper):
    """Add the advice terms of each step to ``info``; the returned reward stays R.

    ``info["advice"]``: ``scale * (F(s') + offset)`` of the reached states s', shape (B,)
    (:func:`scaled_advice`);
    ``info["env_reward"]``: the environment reward R, shape (B,).

    Args:
        env: a vector env whose sub-envs are wrapped in :class:`StateInfo`.
        advice: the advice reward F (:class:`EnvRewardAdvice` for F = R), or None for zeros
            (the ``ppo`` baseline).
        scale: multiplies F (``--advice-scale``).
        offset: added to F before ``scale`` (:attr:`TrainConfig.advice_offset`).
    """

    def __init__(
        self,
        env: gym.vector.VectorEnv,
        advice: AdviceFn | None,
        scale: float = 1.0,
        offset: float = 0.0,
    ):
        super().__init__(env)
        self.advice = advice
        self.scale, self.offset = scale, offset

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(actions)
        info["env_reward"] = reward
        if self.advice is None:
            info["advice"] = np.zeros_like(reward)
        elif isinstance(self.advice, EnvRewardAdvice):
            info["advice"] = scaled_advice(reward, self.scale, self.offset)
        else:
            qpos = reached_qpos(info, terminated | truncated)
            info["advice"] = scaled_advice(self.advice(qpos), self.scale, self.offset)
        return obs, reward, terminated, truncated, info


def scaled_advice(raw: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """The shaping term's F: ``scale * (F + offset)``, the one place both are applied."""
    scaled: np.ndarray = scale * (np.asarray(raw, dtype=np.float64) + offset)
    return scaled
