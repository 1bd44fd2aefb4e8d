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

R, F, z_phi and V at the candidates are :mod:`engine.rl.reward_terms`'s, which says how
each is evaluated. The tree being replayed supplies only the bracket and the candidates; F comes
from it only for a run saved without ``advice.json`` (trained with a plain F callable). ``ppo``
runs have z = 0 and ``ppo-shaped`` runs z = 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.errors import InputError
from engine.judges import judge_name
from engine.rl.advice_fn import advice_reward, pool_reward
from engine.rl.behaviour import (
    RolloutOptions,
    behaviour_cache_name,
    occupancy_scores,
    visited_states,
)
from engine.rl.checkpoint import find_checkpoint
from engine.rl.judge_cache import cached_array
from engine.rl.returns import ReturnOptions, return_scores
from engine.rl.reward_terms import candidate_terms, term_scores
from engine.rl.runner import load_run_advice, load_run_pool
from engine.rl.shaping import AdviceFn
from engine.rl.trained import TrainedAgent, deterministic_policy, load_agent
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument, replay


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
