"""What each finished run is measured by, once (``measures/<arm>-<seed>.json``): every judge's
scores on every evaluation bracket, the judges' R there, the ground truth U, and where its
training ended (steps, the return of its last 100 episodes, z).

U is the teacher's own (latent) score, averaged over every state of ``truth_episodes``
deterministic episodes reset from :data:`TRUTH_RESET_SEED0` on: seeds the behaviour judge
never resets from, so that ``behaviour`` and U do not average over the same states.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine.envs import env_model
from engine.errors import InputError
from engine.provenance import git_commit
from engine.rl.behaviour import RolloutOptions, visited_states
from engine.rl.checkpoint import find_checkpoint
from engine.rl.logger import read_metrics
from engine.rl.reward_terms import candidate_terms
from engine.rl.trained import deterministic_policy, load_agent
from engine.teachers import POSTURE_SCORES
from engine.treefile import TreeDocument
from engine.validation.design import TRUTH_RESET_SEED0, Plan
from engine.validation.runs import (
    measured,
    measures_path,
    read_json,
    run_dir,
    train_task,
)
from engine.validation.workers import Task, Workers
from engine.verdict_runs import judge_scores

#: The judges validated: the two the verdict offers, and the shaped critic as a reference.
JUDGES = ("return", "behaviour", "shaped-value")
MAX_EPISODE_STEPS = 1000  # the MuJoCo envs' own time limit
#: A teacher's latent score: states ``(T, nq)`` and the env's model -> scores ``(T,)``.
PostureScore = Callable[[np.ndarray, Any], np.ndarray]


def truth_states(run: Path, env_id: str, episodes: int) -> np.ndarray:
    """``qpos`` of every state of ``episodes`` deterministic episodes of the run's last
    checkpoint, reset from :data:`TRUTH_RESET_SEED0` on (no burn-in), shape ``(T, nq)``:
    the states U averages over, and the evaluation states round 2 keeps."""
    policy = deterministic_policy(load_agent(find_checkpoint(run)))
    options = RolloutOptions(
        episodes=episodes,
        max_steps=episodes * MAX_EPISODE_STEPS,
        seed=TRUTH_RESET_SEED0,
        burn_in=0,
    )
    return visited_states(policy, env_id, options)


def posture_truth(qpos: np.ndarray, env_id: str, teacher: str) -> float:
    """U over the given states, shape ``(T, nq)``: the teacher's mean latent score."""
    return float(np.mean(posture_score(teacher)(qpos, env_model(env_id))))


def posture_score(teacher: str) -> PostureScore:
    """The teacher's latent score of states.

    Raises:
        InputError: the teacher has none (``good``, ``random``).
    """
    if teacher not in POSTURE_SCORES:
        raise InputError(f"validation needs a posture teacher: {', '.join(POSTURE_SCORES)}")
    return POSTURE_SCORES[teacher]


def teacher_truth(run: Path, env_id: str, teacher: str, episodes: int) -> float:
    """U: the teacher's mean score over every state of ``episodes`` deterministic episodes
    of the run's last checkpoint (the behaviour judge's rollouts, from other reset seeds).

    Raises:
        InputError: the teacher has no latent posture score (``good``, ``random``).
    """
    posture_score(teacher)  # refuse before rolling out
    return posture_truth(truth_states(run, env_id, episodes), env_id, teacher)


def measure(out: Path, plan: Plan, task: Task, brackets: list[TreeDocument]) -> dict[str, Any]:
    """The run's measures, computed and saved once (with the commit that measured them)."""
    path = measures_path(out, task)
    if path.is_file():
        return read_json(path)
    torch.set_num_threads(1)  # one core per run: complete_all measures several at once
    run = run_dir(out, *task)
    agent = load_agent(find_checkpoint(run))
    found = {
        "truth": teacher_truth(run, plan.env_id, plan.teacher, plan.truth_episodes),
        "scores": {
            judge: [judge_scores([run], b, judge)[0].tolist() for b in brackets] for judge in JUDGES
        },
        "reward": [candidate_terms(agent, b).reward.tolist() for b in brackets],
        "train": training_end(run),
        "commit": git_commit(),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(found) + "\n")
    return found


#: What a measure keeps of the run's last metrics row: how far it trained and what it earned.
TRAINING_END = ("timesteps", "return_100", "episode_length", "z_mean")


def training_end(run: Path) -> dict[str, Any]:
    """The run's last metrics row, in part: kept with the measures, so that what the run
    earned stays known where its folder does not (another machine)."""
    last = read_metrics(run)[-1]
    return {key: last[key] for key in TRAINING_END}


def complete(out: Path, plan: Plan, task: Task, brackets: list[TreeDocument]) -> dict[str, Any]:
    """The run's measures: trained first (or resumed) unless they are saved already."""
    if not measured(out, task):
        train_task(out, plan, task)
    return measure(out, plan, task, brackets)


def complete_all(
    out: Path, plan: Plan, tasks: list[Task], brackets: list[TreeDocument], workers: Workers
) -> dict[Task, dict[str, Any]]:
    """Every run trained and measured by ``workers`` (each run on one core); each run is
    measured as soon as it is trained, so a stopped validation keeps every finished run."""
    found = workers.map(partial(complete, out, plan, brackets=brackets), tasks)
    return dict(zip(tasks, found, strict=True))
