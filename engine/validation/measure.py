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

from engine.envs import make_env
from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.rl.agent_judge import candidate_terms
from engine.rl.checkpoint import find_checkpoint
from engine.rl.trained import deterministic_policy, load_agent
from engine.teachers import POSTURE_SCORES
from engine.treefile import TreeDocument
from engine.validation.design import TRUTH_RESET_SEED0, Plan
from engine.validation.runs import Task, read_json, run_dir
from engine.verdict_runs import judge_scores

#: The judges validated: the two the verdict offers, and the shaped critic as a reference.
JUDGES = ("return", "behaviour", "shaped-value")
MAX_EPISODE_STEPS = 1000


def teacher_truth(run: Path, env_id: str, teacher: str, episodes: int) -> float:
    """U: the teacher's mean score over ``episodes`` deterministic episodes of the run's last
    checkpoint.

    Raises:
        InputError: the teacher has no latent posture score (``good``, ``random``).
    """
    if teacher not in POSTURE_SCORES:
        raise InputError(f"validation needs a posture teacher: {', '.join(POSTURE_SCORES)}")
    score = POSTURE_SCORES[teacher]
    act = deterministic_policy(load_agent(find_checkpoint(run)))
    env = make_env(env_id)
    space, values = box(env.action_space), []
    for episode in range(episodes):
        obs, _ = env.reset(seed=TRUTH_RESET_SEED0 + episode)
        for _ in range(MAX_EPISODE_STEPS):
            obs, _, terminated, truncated, _ = env.step(np.clip(act(obs), space.low, space.high))
            base = mujoco_base(env)
            values.append(float(score(base.data.qpos[None], base.model)[0]))
            if terminated or truncated:
                break
    env.close()
    return float(np.mean(values))


def measure(out: Path, plan: Plan, task: Task, brackets: list[TreeDocument]) -> dict[str, Any]:
    """The run's measures, computed and saved once."""
    path = out / "measures" / f"{task[0]}-{task[1]}.json"
    if path.is_file():
        return read_json(path)
    torch.set_num_threads(1)  # one core per run: measure_all measures several at once
    run = run_dir(out, *task)
    found = {
        "truth": teacher_truth(run, plan.env_id, plan.teacher, plan.truth_episodes),
        "scores": {
            judge: [judge_scores([run], b, judge)[0].tolist() for b in brackets] for judge in JUDGES
        },
        "reward": [
            candidate_terms(load_agent(find_checkpoint(run)), b).reward.tolist() for b in brackets
        ],
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
