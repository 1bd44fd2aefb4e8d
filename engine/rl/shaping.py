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

:class:`AdviceWrapper` is the public face of the same terms for training loops outside ACV:
one env, the shaped reward returned, R and F in ``info``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol, SupportsFloat

import gymnasium as gym
import numpy as np

from engine.advice import AdviceMode, AdviceReward
from engine.errors import InputError
from engine.gym_types import mujoco_base
from engine.treefile import TreeDocument, load_tree, tree_from_json


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


TreeSource = TreeDocument | str | Path | Mapping[str, Any]


def advice_tree(source: TreeSource) -> TreeDocument:
    """A person's tree from wherever ACV hands it out, validated: a :class:`TreeDocument`;
    the path of an ``acv.tree/1`` file (``acv tournament``, a study's ``tree.json``
    download); the JSON of ``GET /api/participants/{id}/tree``, parsed (a mapping) or as
    text (the ``document`` column of a study's exported ``trees``).

    Raises:
        InputError: it is no valid ``acv.tree/1`` document.
    """
    if isinstance(source, TreeDocument):
        return source
    if isinstance(source, Mapping):
        return tree_from_json(dict(source))
    if isinstance(source, str) and source.lstrip().startswith("{"):
        try:
            return tree_from_json(json.loads(source))
        except json.JSONDecodeError as exc:
            raise InputError(f"not an acv.tree/1 document: invalid JSON ({exc})") from exc
    return load_tree(source)


class AdviceWrapper(gym.Wrapper):
    """A person's advice as a reward term in any training loop (Stable-Baselines3, CleanRL,
    your own PPO or SAC): the step's reward becomes ``R + scale * (F(s') + offset)``, exactly
    what ACV's ``ppo-shaped`` arm optimises (z = 1), with F of the reached state s' from the
    person's Preference Tree (:class:`engine.advice.AdviceReward`). ``info["R"]`` holds the
    env's reward and ``info["F"]`` the added term ``scale * (F + offset)``, apart.

    A per-env wrapper: put it inside SB3's ``DummyVecEnv``/``SubprocVecEnv`` or Gymnasium's
    vector envs (``make_vec(..., wrappers=[...])``). BiPaRS (``bipars-em``, ``bipars-mgl``)
    cannot be a wrapper: its weight z_phi(s) is learned together with the policy, so it lives
    in ACV's trainer.

    Args:
        env: a Gymnasium MuJoCo env of the tree's env id.
        tree: the person's tree (:func:`advice_tree` says where from).
        scale: multiplies the advice (ACV's ``--advice-scale``, λ).
        offset: added to F before ``scale`` (``+1`` keeps F + 1 >= 0, so that no agent
            escapes the advice by ending its episodes: docs/validation.md §2).
        mode: ``nearest`` (default), ``softmax`` or ``paper-min``.
        depth_factor: ``none`` (default) or ``paper``.
        kappa: the softmax mode's inverse temperature.

    Raises:
        InputError: the tree is invalid or for another env.
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        tree: TreeSource,
        *,
        scale: float = 1.0,
        offset: float = 0.0,
        mode: AdviceMode = "nearest",
        depth_factor: str = "none",
        kappa: float = 10.0,
    ):
        super().__init__(env)
        doc = advice_tree(tree)
        env_id = env.spec.id if env.spec is not None else None
        if env_id != doc.env_id:
            raise InputError(f"the tree is for {doc.env_id}, the env is {env_id}")
        self.advice = AdviceReward.from_tree(doc, mode, depth_factor, kappa)
        self.scale, self.offset = scale, offset

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        reached = mujoco_base(self.env).data.qpos[None]  # (1, nq)
        advice = float(scaled_advice(self.advice(reached), self.scale, self.offset)[0])
        return obs, float(reward) + advice, terminated, truncated, info | {"R": reward, "F": advice}
