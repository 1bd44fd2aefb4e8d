"""The verdict of :mod:`engine.verdict` for training runs on disk: each run's judge scores at
its last checkpoint over the advice bracket, grouped into advised, baseline and pilot arms.

Kept apart from :mod:`engine.verdict`, which stays free of torch.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from engine.errors import InputError
from engine.judges import judge_name
from engine.rl.agent_judge import agent_tree
from engine.rl.behaviour import RolloutOptions
from engine.rl.checkpoint import find_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.reward_terms import candidate_terms
from engine.rl.runner import load_run_config
from engine.rl.trained import load_agent
from engine.treefile import TreeDocument
from engine.verdict import (
    Verdict,
    VerdictInputs,
    VerdictOptions,
    advice_scores,
    bracket_pairs,
)
from engine.verdict_outcome import verdict


def check_arms(
    advice: TreeDocument,
    advised: Sequence[Path],
    baseline: Sequence[Path],
    pilot: Sequence[Path],
) -> None:
    """Raise :class:`InputError` unless the runs make a matched design.

    Every run is on the advice's env with one budget; the advised runs train with advice and
    the others without; no run is listed twice; and the pilot seeds are disjoint from the
    evaluation seeds (advised and baseline), or the pilot would pick the matches on seeds it
    is then scored on (docs/method.md §2.11).
    """
    paths = [*advised, *baseline, *pilot]
    if len({Path(p).resolve() for p in paths}) != len(paths):
        raise InputError("a run is listed twice: each run belongs to one arm once")
    configs = {Path(p): load_run_config(Path(p)) for p in paths}
    for path, cfg in configs.items():
        if cfg.env_id != advice.env_id:
            raise InputError(f"{path} trained on {cfg.env_id}, the advice is for {advice.env_id}")
    if len({cfg.total_timesteps for cfg in configs.values()}) > 1:
        raise InputError("the runs differ in budget (total timesteps): the arms are not matched")
    _check_advice_use(advised, configs, True)
    _check_advice_use([*baseline, *pilot], configs, False)
    shared = {configs[Path(p)].seed for p in pilot} & {
        configs[Path(p)].seed for p in [*advised, *baseline]
    }
    if shared:
        raise InputError(
            f"pilot seed(s) {', '.join(map(str, sorted(shared)))} are also evaluation seeds: "
            "the pilot runs must use other seeds"
        )


def _check_advice_use(
    runs: Sequence[Path], configs: dict[Path, TrainConfig], with_advice: bool
) -> None:
    for path in runs:
        if configs[Path(path)].uses_advice != with_advice:
            arm = "advised" if with_advice else "baseline and pilot"
            raise InputError(
                f"{path} ({configs[Path(path)].algo}) cannot be in the {arm} arm: "
                f"{arm} runs train {'with' if with_advice else 'without'} advice"
            )


def judge_scores(
    runs: Sequence[Path],
    advice: TreeDocument,
    judge: str,
    rollouts: RolloutOptions = RolloutOptions(),
) -> np.ndarray:
    """Each run's ``judge`` score of every candidate, at its last checkpoint.

    Returns:
        shape ``(len(runs), N)``, candidates in id order.
    """
    judge = judge_name(judge)
    rows = np.zeros((len(runs), len(advice.candidates)))
    for i, run in enumerate(runs):
        scores = agent_tree(Path(run), None, judge, advice, rollouts=rollouts).scores
        if scores is None:  # agent_tree always records them; a guard for the type checker
            raise InputError(f"{run}: the judge {judge!r} gave no scores")
        rows[i] = [scores[c.id] for c in advice.candidates]
    return rows


def judges_reward(runs: Sequence[Path], advice: TreeDocument) -> np.ndarray:
    """The judges' R per candidate, shape ``(N,)``: the stored env reward minus the control
    cost of each run's mean action there, averaged over ``runs`` (the pilot runs, so that the
    immediate-R contested matches use the R the no-advice judge sees)."""
    rewards = [
        candidate_terms(load_agent(find_checkpoint(Path(run))), advice).reward for run in runs
    ]
    mean: np.ndarray = np.mean(rewards, axis=0)
    return mean


def runs_verdict(
    advice: TreeDocument,
    arms: tuple[Sequence[Path], Sequence[Path], Sequence[Path]],
    judge: str,
    rng: np.random.Generator,
    options: VerdictOptions = VerdictOptions(),
    rollouts: RolloutOptions = RolloutOptions(),
) -> Verdict:
    """The verdict of the advised runs against the baseline, contested matches picked by the
    pilot runs, on the advice tree's bracket. Immediate-R contested uses the pilot judges' R
    (:func:`judges_reward`).

    Args:
        advice: the advice tree.
        arms: run directories ``(advised, baseline, pilot)``.
        judge: one of :data:`engine.judges.JUDGES` (or a legacy name).
        rng: the verdict's bootstrap.
        options: margins, minimum matches, level and power.
        rollouts: the behaviour judge's rollouts.
    """
    check_arms(advice, *arms)
    advised, baseline, pilot = (judge_scores(runs, advice, judge, rollouts) for runs in arms)
    reward = judges_reward(arms[2], advice) if len(arms[2]) else None
    inputs = VerdictInputs(
        advice_scores(advice), advised, baseline, pilot, bracket_pairs(advice), reward
    )
    return verdict(inputs, rng, options)
