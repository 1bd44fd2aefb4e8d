"""The Agent Preference Tree: the advice bracket replayed with the agent as the judge.

"Anytime" (paper, section III): at any checkpoint, each candidate s of the Human Preference
Tree's bracket gets a score from the agent, and the same bracket (same candidates, same first
round) is played again with the higher score winning each match. Judges:

- ``shaped`` (default): g(s) = R(s) + z_phi(s) F(s), the agent's shaped reward;
- ``shaping``: z_phi(s) F(s), the part of it that comes from the advice;
- ``value``: the shaped critic V(s).

R(s) is the candidate's stored env reward, F the advice reward the agent trained with (built
from the run's ``advice.json``, times ``advice_scale``), and z_phi and V are evaluated on the
candidate's observation (restored with :func:`engine.envs.restore`, normalised as in
training). The tree being replayed supplies only the bracket and the candidates; F comes from
it only for a run saved without ``advice.json`` (trained with a plain F callable). ``ppo`` runs
have z = 0 and ``ppo-shaped`` runs z = 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from engine.envs import make_env, restore
from engine.errors import InputError
from engine.pipeline import replay
from engine.rl.checkpoint import find_checkpoint, load_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer
from engine.rl.runner import advice_reward, load_run_advice
from engine.rl.shaping import AdviceFn
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument

JUDGES: tuple[str, ...] = ("shaped", "shaping", "value")


@dataclass(frozen=True)
class TrainedAgent:
    """The networks and normaliser of one checkpoint.

    Attributes:
        config: the run's configuration.
        agent: actor, critics and z_phi, in eval mode.
        obs_norm: the observation normaliser at that checkpoint.
        timesteps: env steps trained.
    """

    config: TrainConfig
    agent: Agent
    obs_norm: ObsNormalizer
    timesteps: int


def load_agent(path: Path) -> TrainedAgent:
    """Rebuild the agent of a checkpoint file.

    Raises:
        InputError: the file is not an ACV checkpoint or its networks do not fit its config.
    """
    state = load_checkpoint(path)
    try:
        cfg = TrainConfig.from_json(state["config"])
        agent = Agent(int(state["obs_dim"]), int(state["act_dim"]), cfg.hidden, cfg.algo,
                      cfg.z_max, cfg.z_init)
        agent.load_state_dict(state["agent"])
        obs_norm = ObsNormalizer((int(state["obs_dim"]),), enabled=cfg.norm_obs)
        obs_norm.load_state_dict(state["obs_norm"])
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path} is a damaged checkpoint ({type(exc).__name__}: {exc})"
                         ) from exc
    return TrainedAgent(cfg, agent.eval(), obs_norm, int(state["timesteps"]))


@torch.no_grad()
def agent_scores(trained: TrainedAgent, doc: TreeDocument, judge: str = "shaped",
                 advice: AdviceFn | None = None) -> dict[int, float]:
    """The agent's score of every candidate of ``doc`` under ``judge``.

    Args:
        trained: the checkpoint's networks.
        doc: the tree whose candidates are scored.
        judge: one of :data:`JUDGES`.
        advice: the F the agent trained with; built from ``doc`` when None (right only when
            ``doc`` is the run's own advice tree).
    """
    if judge not in JUDGES:
        raise InputError(f"unknown judge {judge!r}: expected one of {', '.join(JUDGES)}")
    cfg = trained.config
    if doc.env_id != cfg.env_id:
        raise InputError(f"the tree is for {doc.env_id}, but the agent was trained on "
                         f"{cfg.env_id}")
    x = candidate_inputs(trained, doc)
    if judge == "value":
        scores = trained.agent.values(x)[0].double().numpy()
    else:
        qpos = np.stack([c.qpos for c in doc.candidates])
        f = advice if advice is not None else advice_reward(cfg, doc)
        shaping = trained.agent.z(x).double().numpy() * cfg.advice_scale * f(qpos)
        reward = np.array([c.env_reward for c in doc.candidates])
        scores = shaping if judge == "shaping" else reward + shaping
    return {c.id: float(s) for c, s in zip(doc.candidates, scores, strict=True)}


def candidate_inputs(trained: TrainedAgent, doc: TreeDocument) -> torch.Tensor:
    """The candidates' observations, normalised as the agent saw them, shape ``(N, obs_dim)``.
    """
    env = make_env(doc.env_id)
    try:
        obs = np.stack([restore(env, c.qpos, c.qvel) for c in doc.candidates])
    finally:
        env.close()
    return torch.from_numpy(trained.obs_norm(obs))


@torch.no_grad()
def candidate_z(trained: TrainedAgent, doc: TreeDocument) -> dict[int, float]:
    """The shaping weight z_phi(s) the agent gives each candidate (0 for ``ppo``)."""
    z = trained.agent.z(candidate_inputs(trained, doc)).double().numpy()
    return {c.id: float(v) for c, v in zip(doc.candidates, z, strict=True)}


def agent_tree(run_dir: Path, step: int | None = None, judge: str = "shaped",
               advice: TreeDocument | None = None) -> TreeDocument:
    """The Agent Preference Tree of a run's checkpoint over the advice tree's bracket.

    Args:
        run_dir: the training run directory.
        step: checkpoint timesteps; the latest when None.
        judge: one of :data:`JUDGES`.
        advice: the tree whose bracket is replayed; by default the run's ``advice.json``.
            The judge's F is always the run's own (see the module docstring).

    Raises:
        InputError: no advice tree, no such checkpoint, a damaged checkpoint, another env.
    """
    own, doc = _advice_trees(run_dir, advice)  # before the checkpoint: the clearer error
    return _replay_as(load_agent(find_checkpoint(run_dir, step)), doc, own, judge)


def trained_agent_tree(trained: TrainedAgent, run_dir: Path, judge: str = "shaped",
                       advice: TreeDocument | None = None) -> TreeDocument:
    """:func:`agent_tree` for a checkpoint already loaded from ``run_dir`` (callers that also
    need its z or scores load it once)."""
    own, doc = _advice_trees(run_dir, advice)
    return _replay_as(trained, doc, own, judge)


def _advice_trees(run_dir: Path, advice: TreeDocument | None
                  ) -> tuple[TreeDocument | None, TreeDocument]:
    """The run's own advice tree (None without ``advice.json``) and the tree to replay."""
    own = load_run_advice(run_dir)
    doc = advice if advice is not None else own
    if doc is None:
        raise InputError(f"{run_dir} was trained without advice: pass the tree to replay")
    return own, doc


def _replay_as(trained: TrainedAgent, doc: TreeDocument, own: TreeDocument | None,
               judge: str) -> TreeDocument:
    """``doc``'s bracket replayed with the agent's scores (F from its own advice)."""
    f = advice_reward(trained.config, own) if own is not None else None
    scores = agent_scores(trained, doc, judge, f)
    return replay(doc, ScoreJudge(scores), f"agent:{judge}@{trained.timesteps}", scores=scores)
