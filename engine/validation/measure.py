"""What each finished run is measured by, once (``measures/<arm>-<seed>.json``): every judge's
scores on every evaluation bracket, the judges' R there, and the ground truth U.

U is the teacher's own (latent) score, averaged over every state of ``truth_episodes``
deterministic episodes reset from :data:`TRUTH_RESET_SEED0` on: seeds the behaviour judge
never resets from, so that ``behaviour`` and U do not average over the same states.
"""

from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
import torch

from engine.envs import env_model
from engine.errors import InputError
from engine.rl.agent_judge import candidate_terms
from engine.rl.behaviour import RolloutOptions, visited_states
from engine.rl.checkpoint import find_checkpoint
from engine.rl.trained import deterministic_policy, load_agent
from engine.teachers import POSTURE_SCORES
from engine.treefile import TreeDocument
from engine.validation.design import TRUTH_RESET_SEED0, Plan
from engine.validation.runs import Task, read_json, run_dir
from engine.verdict_runs import judge_scores

#: The judges validated: the two the verdict offers, and the shaped critic as a reference.
JUDGES = ("return", "behaviour", "shaped-value")
MAX_EPISODE_STEPS = 1000  # the MuJoCo envs' own time limit


def teacher_truth(run: Path, env_id: str, teacher: str, episodes: int) -> float:
    """U: the teacher's mean score over every state of ``episodes`` deterministic episodes
    of the run's last checkpoint (the behaviour judge's rollouts, from other reset seeds).

    Raises:
        InputError: the teacher has no latent posture score (``good``, ``random``).
    """
    if teacher not in POSTURE_SCORES:
        raise InputError(f"validation needs a posture teacher: {', '.join(POSTURE_SCORES)}")
    policy = deterministic_policy(load_agent(find_checkpoint(run)))
    options = RolloutOptions(
        episodes=episodes,
        max_steps=episodes * MAX_EPISODE_STEPS,
        seed=TRUTH_RESET_SEED0,
        burn_in=0,
    )
    qpos = visited_states(policy, env_id, options)
    return float(np.mean(POSTURE_SCORES[teacher](qpos, env_model(env_id))))


def measure(out: Path, plan: Plan, task: Task, brackets: list[TreeDocument]) -> dict[str, Any]:
    """The run's measures, computed and saved once."""
    path = out / "measures" / f"{task[0]}-{task[1]}.json"
    if path.is_file():
        return read_json(path)
    torch.set_num_threads(1)  # one core per run: measure_all measures several at once
    run = run_dir(out, *task)
    agent = load_agent(find_checkpoint(run))
    found = {
        "truth": teacher_truth(run, plan.env_id, plan.teacher, plan.truth_episodes),
        "scores": {
            judge: [judge_scores([run], b, judge)[0].tolist() for b in brackets] for judge in JUDGES
        },
        "reward": [candidate_terms(agent, b).reward.tolist() for b in brackets],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(found) + "\n")
    return found


def measure_all(
    out: Path, plan: Plan, tasks: list[Task], brackets: list[TreeDocument], jobs: int
) -> dict[Task, dict[str, Any]]:
    """Every run's measures, ``jobs`` runs at a time (each one core: rollouts and judges)."""
    if jobs <= 1:
        return {task: measure(out, plan, task, brackets) for task in tasks}
    # spawn, because torch and MuJoCo are not fork-safe
    with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
        futures = {task: pool.submit(measure, out, plan, task, brackets) for task in tasks}
        return {task: future.result() for task, future in futures.items()}
