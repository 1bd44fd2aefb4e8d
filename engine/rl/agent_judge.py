"""The Agent Preference Tree: the advice bracket replayed with the agent as the judge.

"Anytime" (paper, section III): at any checkpoint, each candidate s of the Human Preference
Tree's bracket gets a score from the agent, and the same bracket (same candidates, same first
round) is played again with the higher score winning each match. Judges:

- ``return`` (a default verdict judge; it failed the validation on known answers): the
  environment return the agent's deterministic policy earns from s (:mod:`engine.rl.returns`);
- ``behaviour`` (the other default; it failed the validation too): what the agent does: its
  mean occupancy near s over deterministic rollouts after a burn-in
  (:mod:`engine.rl.behaviour`), a *revealed-preference* tree;
- ``shaped``: g(s) = R(s) + z_phi(s) F(s), the agent's shaped reward, and ``shaping``:
  z_phi(s) F(s), the part of it that comes from the advice. Diagnostics ("is your advice
  still in its reward?"): they restate the advice and never lead a verdict;
- ``shaped-value``: the shaped critic V(s) (it learns R + z F, so it too partly restates the
  advice; stored reports from before the rename call it ``value``).

R(s) is the reward the agent gets in s: the candidate's stored env reward minus the control
cost of the policy's mean action there (the stored reward has no action, so no control cost).
F is the advice reward the agent trained with (built from the run's ``advice.json``, times
``advice_scale``; F = R for advice mode ``reward``; none for ``ppo``), and z_phi, V and the
action are evaluated on the candidate's observation (restored with
:func:`engine.envs.restore`, normalised as in training). The tree being replayed supplies
only the bracket and the candidates; F comes from it only for a run saved without
``advice.json`` (trained with a plain F callable). ``ppo`` runs have z = 0 and ``ppo-shaped``
runs z = 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from engine.envs import make_env, restore
from engine.errors import InputError
from engine.gym_types import box
from engine.judges import judge_name
from engine.rewards import control_cost
from engine.rl.behaviour import (
    RolloutOptions,
    behaviour_cache_name,
    occupancy_scores,
    visited_states,
)
from engine.rl.checkpoint import find_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.judge_cache import cached_array
from engine.rl.returns import ReturnOptions, return_scores
from engine.rl.runner import advice_reward, load_run_advice, load_run_pool, pool_reward
from engine.rl.shaping import AdviceFn, EnvRewardAdvice, scaled_advice
from engine.rl.trained import TrainedAgent, deterministic_policy, load_agent
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument, replay


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


def agent_scores(
    trained: TrainedAgent,
    doc: TreeDocument,
    judge: str = "return",
    advice: AdviceFn | None = None,
    *,
    run_dir: Path | None = None,
    rollouts: RolloutOptions = RolloutOptions(),
    returns: ReturnOptions = ReturnOptions(),
) -> dict[int, float]:
    """The agent's score of every candidate of ``doc`` under ``judge``.

    Args:
        trained: the checkpoint's networks.
        doc: the tree whose candidates are scored.
        judge: one of :data:`JUDGES` (or a legacy name, :data:`LEGACY_JUDGES`).
        advice: the F the agent trained with (see :func:`candidate_terms`).
        run_dir: where the simulating judges cache their rollouts (no cache when None).
        rollouts: the behaviour judge's rollouts.
        returns: the return judge's rollouts.
    """
    judge = judge_name(judge)
    _check_env(trained, doc)
    if judge == "behaviour":
        return behaviour_scores(trained, doc, run_dir=run_dir, rollouts=rollouts)
    if judge == "return":
        return return_scores(
            deterministic_policy(trained),
            doc,
            returns,
            run_dir=run_dir,
            checkpoint_digest=trained.digest,
        )
    return term_scores(candidate_terms(trained, doc, advice), judge, doc)


def _check_env(trained: TrainedAgent, doc: TreeDocument) -> None:
    if doc.env_id != trained.config.env_id:
        raise InputError(
            f"the tree is for {doc.env_id}, but the agent was trained on {trained.config.env_id}"
        )


def behaviour_scores(
    trained: TrainedAgent,
    doc: TreeDocument,
    *,
    run_dir: Path | None = None,
    rollouts: RolloutOptions = RolloutOptions(),
) -> dict[int, float]:
    """The behaviour judge's scores: occupancy of the policy's rollouts near each candidate
    (cached by the checkpoint's content hash)."""
    _check_env(trained, doc)
    return occupancy_scores(behaviour_visited(trained, run_dir=run_dir, rollouts=rollouts), doc)


def behaviour_visited(
    trained: TrainedAgent, *, run_dir: Path | None = None, rollouts: RolloutOptions
) -> np.ndarray:
    """``qpos`` of the states the behaviour judge's rollouts visit, shape ``(T, nq)``, cached
    in ``run_dir`` by the checkpoint's content hash and the rollout options."""
    return cached_array(
        run_dir if trained.digest else None,
        behaviour_cache_name(trained.digest, rollouts),
        lambda: visited_states(deterministic_policy(trained), trained.config.env_id, rollouts),
    )


@torch.no_grad()
def candidate_z(trained: TrainedAgent, doc: TreeDocument) -> dict[int, float]:
    """The shaping weight z_phi(s) the agent gives each candidate (0 for ``ppo``)."""
    z = candidate_terms(trained, doc).z
    return {c.id: float(v) for c, v in zip(doc.candidates, z, strict=True)}


def agent_tree(
    run_dir: Path,
    step: int | None = None,
    judge: str = "return",
    advice: TreeDocument | None = None,
    *,
    rollouts: RolloutOptions = RolloutOptions(),
    returns: ReturnOptions = ReturnOptions(),
) -> TreeDocument:
    """The Agent Preference Tree of a run's checkpoint over the advice tree's bracket.

    Args:
        run_dir: the training run directory.
        step: checkpoint timesteps; the latest when None.
        judge: one of :data:`JUDGES`.
        advice: the tree whose bracket is replayed; by default the run's ``advice.json``.
            The judge's F is always the run's own (see the module docstring).
        rollouts: the behaviour judge's rollouts.
        returns: the return judge's rollouts.

    Raises:
        InputError: no advice tree, no such checkpoint, a damaged checkpoint, another env.
    """
    judge = judge_name(judge)
    own, doc = _advice_trees(run_dir, advice)  # before the checkpoint: the clearer error
    trained = load_agent(find_checkpoint(run_dir, step))
    return _judged(trained, doc, own, judge, run_dir, rollouts, returns)


def trained_agent_tree(
    trained: TrainedAgent, run_dir: Path, judge: str = "return", advice: TreeDocument | None = None
) -> TreeDocument:
    """:func:`agent_tree` for a checkpoint already loaded from ``run_dir`` (callers that also
    need its z or scores load it once)."""
    judge = judge_name(judge)
    own, doc = _advice_trees(run_dir, advice)
    return _judged(trained, doc, own, judge, run_dir, RolloutOptions(), ReturnOptions())


def _advice_trees(
    run_dir: Path, advice: TreeDocument | None
) -> tuple[TreeDocument | None, TreeDocument]:
    """The run's own advice tree (None without ``advice.json``) and the tree to replay."""
    own = load_run_advice(run_dir)
    doc = advice if advice is not None else own
    if doc is None:
        raise InputError(f"{run_dir} was trained without advice: pass the tree to replay")
    return own, doc


def run_advice_fn(
    trained: TrainedAgent, own: TreeDocument | None, run_dir: Path | None = None
) -> AdviceFn | None:
    """The F the agent trained with: from the run's advice pool when it has one, else from
    its own advice tree (None without either)."""
    pool = load_run_pool(run_dir) if run_dir is not None else None
    if pool is not None:
        return pool_reward(trained.config, pool)
    return advice_reward(trained.config, own) if own is not None else None


def _judged(
    trained: TrainedAgent,
    doc: TreeDocument,
    own: TreeDocument | None,
    judge: str,
    run_dir: Path | None,
    rollouts: RolloutOptions,
    returns: ReturnOptions,
) -> TreeDocument:
    """``doc``'s bracket replayed with the agent's scores (F from its own advice)."""
    scores = agent_scores(
        trained,
        doc,
        judge,
        run_advice_fn(trained, own, run_dir),
        run_dir=run_dir,
        rollouts=rollouts,
        returns=returns,
    )
    return replay_as(trained, doc, judge, scores)


def replay_as(
    trained: TrainedAgent, doc: TreeDocument, judge: str, scores: dict[int, float]
) -> TreeDocument:
    """``doc``'s bracket replayed by ``scores``, named ``agent:<judge>@<timesteps>``."""
    return replay(doc, ScoreJudge(scores), f"agent:{judge}@{trained.timesteps}", scores=scores)
