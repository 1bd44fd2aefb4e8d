"""The agent's reward terms at a tree's candidates: R, F, z_phi and V.

They make the judges of reward terms of :mod:`engine.rl.agent_judge` (``shaped``: R + z F,
``shaping``: z F, ``shaped-value``: V) and the R that every judge reads (:func:`judge_reward`).

R(s) is the reward the agent gets in s: the candidate's stored env reward minus the control
cost of the policy's mean action there (the stored reward has no action, so no control cost).
F is the advice reward the agent trained with (built from the run's ``advice.json``, times
``advice_scale``; F = R for advice mode ``reward``; none for ``ppo``), and z_phi, V and the
action are evaluated on the candidate's observation (restored with
:func:`engine.envs.restore`, normalised as in training).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from engine.envs import make_env, restore
from engine.errors import InputError
from engine.gym_types import box
from engine.rewards import control_cost
from engine.rl.advice_fn import advice_reward
from engine.rl.config import TrainConfig
from engine.rl.shaping import AdviceFn, EnvRewardAdvice, scaled_advice
from engine.rl.trained import TrainedAgent
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class CandidateTerms:
    """The agent's reward terms at each candidate, arrays of shape ``(N,)`` in id order.

    Attributes:
        reward: R(s): stored env reward minus the control cost of the policy's mean action.
        advice: F(s) after ``advice_scale`` (0 without advice).
        z: the shaping weight z_phi(s).
        value: V(s) of the shaped critic.
    """

    reward: np.ndarray
    advice: np.ndarray
    z: np.ndarray
    value: np.ndarray

    @property
    def shaping(self) -> np.ndarray:
        """z_phi(s) F(s)."""
        shaping: np.ndarray = self.z * self.advice
        return shaping

    @property
    def shaped(self) -> np.ndarray:
        """R(s) + z_phi(s) F(s)."""
        shaped: np.ndarray = self.reward + self.shaping
        return shaped


@torch.no_grad()
def candidate_terms(
    trained: TrainedAgent, doc: TreeDocument, advice: AdviceFn | None = None
) -> CandidateTerms:
    """R, F, z and V of every candidate of ``doc`` (see the module docstring).

    Args:
        advice: the F the agent trained with; built from ``doc`` when None (right only when
            ``doc`` is the run's own advice tree).
    """
    cfg = trained.config
    if doc.env_id != cfg.env_id:
        raise InputError(f"the tree is for {doc.env_id}, but the agent was trained on {cfg.env_id}")
    env = make_env(doc.env_id)
    try:
        x = torch.from_numpy(
            trained.obs_norm(np.stack([restore(env, c.qpos, c.qvel) for c in doc.candidates]))
        )
        z = trained.agent.z(x)
        space = box(env.action_space)
        actions = trained.agent.actor(x, z).double().numpy().clip(space.low, space.high)
        costs = np.array([control_cost(env, a) for a in actions])
    finally:
        env.close()
    reward = np.array([c.env_reward for c in doc.candidates]) - costs
    return CandidateTerms(
        reward,
        _advice_values(cfg, doc, advice, reward),
        z.double().numpy(),
        trained.agent.values(x)[0].double().numpy(),
    )


def _advice_values(
    cfg: TrainConfig, doc: TreeDocument, advice: AdviceFn | None, reward: np.ndarray
) -> np.ndarray:
    """F at the candidates as the run was shaped (:func:`scaled_advice`); 0 without advice."""
    if not cfg.uses_advice:
        return np.zeros(len(doc.candidates))
    f = advice if advice is not None else advice_reward(cfg, doc)
    raw = (
        reward if isinstance(f, EnvRewardAdvice) else f(np.stack([c.qpos for c in doc.candidates]))
    )
    return scaled_advice(raw, cfg.advice_scale, cfg.advice_offset)


def term_scores(terms: CandidateTerms, judge: str, doc: TreeDocument) -> dict[int, float]:
    """The scores of a judge of reward terms (``shaped``, ``shaping``, ``shaped-value``)."""
    values = {"shaped": terms.shaped, "shaping": terms.shaping, "shaped-value": terms.value}
    return {c.id: float(v) for c, v in zip(doc.candidates, values[judge], strict=True)}


def judge_reward(trained: TrainedAgent, doc: TreeDocument) -> dict[int, float]:
    """The R that the judges use, per candidate id: the stored ``env_reward`` minus the control
    cost of the policy's mean action there (the R of :class:`CandidateTerms`). Conformance and
    the verdict take it as their R map, so that contested matches, the reference and the
    judges all read one R."""
    reward = candidate_terms(trained, doc).reward
    return {c.id: float(r) for c, r in zip(doc.candidates, reward, strict=True)}


@torch.no_grad()
def candidate_z(trained: TrainedAgent, doc: TreeDocument) -> dict[int, float]:
    """The shaping weight z_phi(s) the agent gives each candidate (0 for ``ppo``)."""
    z = candidate_terms(trained, doc).z
    return {c.id: float(v) for c, v in zip(doc.candidates, z, strict=True)}
