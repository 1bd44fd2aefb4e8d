"""What each finished run of round 2 is measured by, once (docs/validation.md §6.3), and the
round end to end: pilots, brackets, every run trained and measured as soon as it is trained.

A run's measures (``measures/<label>-<seed>.json``): on every bracket, every judge's score of
every candidate (the primary's mean similarity is ``behaviour``; the secondary's nearest
share is ``behaviour-nearest``), and the judges' R; the ground truth U under the round's
teacher (and ``standing`` where the round has its bracket); where training ended; the commit.
Its evaluation states (``states/<label>-<seed>.npz``): the states U averages over, every 4th,
float32, so that later statistics and the agent evaluation need no training.
"""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine.advice import AdviceReward
from engine.provenance import git_commit
from engine.rl.agent_judge import behaviour_visited
from engine.rl.behaviour import RolloutOptions, nearest_shares
from engine.rl.checkpoint import find_checkpoint
from engine.rl.reward_terms import candidate_terms
from engine.rl.trained import TrainedAgent, load_agent
from engine.treefile import TreeDocument
from engine.validation.measure import JUDGES, posture_truth, training_end, truth_states
from engine.validation.round2_analysis import write
from engine.validation.round2_runs import (
    Round2Plan,
    make_advice,
    measured,
    measures_path,
    prepare,
    states_path,
    tasks,
    train_all,
    train_task,
)
from engine.validation.runs import run_dir
from engine.validation.workers import Task, Workers
from engine.verdict_runs import judge_scores

#: Every how many evaluation states one is kept.
STATE_STRIDE = 4


def bracket_scores(run: Path, agent: TrainedAgent, doc: TreeDocument) -> dict[str, list[float]]:
    """Each judge's score of each of the bracket's candidates, the secondary's nearest share
    beside them, from the run's last checkpoint ``agent`` (its behaviour rollouts are cached,
    so the nearest share reuses the judge's)."""
    found = {judge: judge_scores([run], doc, judge)[0].tolist() for judge in JUDGES}
    visited = behaviour_visited(agent, run_dir=run, rollouts=RolloutOptions())
    similarity = AdviceReward.from_tree(doc).similarity(visited) if len(visited) else None
    nearest = np.zeros(len(doc.candidates)) if similarity is None else nearest_shares(similarity)
    found["behaviour-nearest"] = nearest.tolist()
    return found


def measure(
    out: Path, plan: Round2Plan, task: Task, brackets: dict[str, TreeDocument]
) -> dict[str, Any]:
    """The run's measures and evaluation states, computed and saved once."""
    path = measures_path(out, task)
    if path.is_file():
        found: dict[str, Any] = json.loads(path.read_text())
        return found
    torch.set_num_threads(1)  # one core per run: several are measured at once
    run = run_dir(out, *task)
    agent = load_agent(find_checkpoint(run))
    states = truth_states(run, plan.env_id, plan.truth_episodes)
    teachers = [plan.teacher] + (["standing"] if "standing" in brackets else [])
    found = {
        "scores": {name: bracket_scores(run, agent, doc) for name, doc in brackets.items()},
        "reward": {
            name: candidate_terms(agent, doc).reward.tolist() for name, doc in brackets.items()
        },
        "truth": {t: posture_truth(states, plan.env_id, t) for t in teachers},
        "train": training_end(run),
        "commit": git_commit(),
    }
    states_path(out, task).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(states_path(out, task), qpos=states[::STATE_STRIDE].astype(np.float32))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(found) + "\n")
    return found


def complete(
    out: Path, plan: Round2Plan, task: Task, brackets: dict[str, TreeDocument]
) -> dict[str, Any]:
    """The run's measures: trained first (or resumed) unless they are saved already."""
    if not measured(out, task):
        train_task(out, plan, task)
    return measure(out, plan, task, brackets)


def run_round(out: Path, plan: Round2Plan, workers: Workers) -> dict[Task, dict[str, Any]]:
    """Round 2 on one env end to end, resumable: the pilots, the brackets and their trees,
    then every run trained and measured (each as soon as it is trained), then the analysis."""
    prepare(out, plan)
    every = tasks(plan)
    train_all(out, plan, every[:2], workers, deadline=None)  # the pilots make the brackets
    brackets = make_advice(out, plan)
    found = workers.map(partial(complete, out, plan, brackets=brackets), every)
    write(out, plan, np.random.default_rng(0))  # summary.json and report.md
    return dict(zip(every, found, strict=True))
