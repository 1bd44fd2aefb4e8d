"""Train and measure the validation's agents, resumably (docs/validation.md §3).

The output folder holds ``validate.json`` (the :class:`Plan`; another plan in the same folder
is refused), ``runs/<arm>-<seed>/`` (ordinary training runs, resumed from their last
checkpoint), ``brackets/bracket_<b>.json`` (the teacher's tree over informative candidates
sampled from a pilot's policy), ``advice/{advice,shuffled,inverted}.json`` (what the arms
train on: bracket 0's tree and its two controls) and ``measures/<arm>-<seed>.json`` (each
finished run's judge scores on every bracket and its ground truth U, measured as soon as it
is trained).

Everything but ``runs/`` is small JSON and is the validation's *state*: a run whose measures
are saved is done and needs no folder, so those files, copied into a fresh ``out`` on another
machine, resume the validation there without training a measured run again.
"""

from __future__ import annotations

import json
import shutil
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import InputError
from engine.informative import sample_informative
from engine.pinned import pin_settings
from engine.pipeline import replay_with_teacher, teacher_bracket
from engine.rl.checkpoint import list_checkpoints
from engine.rl.config import TrainConfig
from engine.rl.runner import train
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument, dump_tree, load_tree, replay
from engine.validation.design import (
    ARM_BY_NAME,
    BASELINE,
    BRACKET_SEED0,
    PILOT,
    AdviceKind,
    Arm,
    BracketPlan,
    Plan,
    TrainingPlan,
)
from engine.validation.workers import Task, Workers

PLAN_FILE = "validate.json"
#: Checkpoints per run: an interrupted validation loses at most a tenth of a run.
CHECKPOINTS = 10
#: F + 1 >= 0 wherever the state is nearest a leaf or the best similarity is >= 0 (leaves are
#: worth -r_b = -1 with the default depth factor): no arm can escape its advice by falling.
#: Without it ``p1-10`` learned to end Hopper's episodes in 6 steps (F < 0 where it starts);
#: the shuffled arms, offset alike, control for the alive bonus it adds.
ADVICE_OFFSET = 1.0


def prepare(out: Path, plan: Plan) -> None:
    """Write ``validate.json``, or check that ``out`` holds this same plan.

    Raises:
        InputError: ``out`` holds a validation with another plan.
    """
    pin_settings(
        out / PLAN_FILE,
        plan.to_json(),
        "a validation",
        normalize=lambda saved: Plan.from_json(saved).to_json(),
    )


def run_dir(out: Path, arm: str, seed: int) -> Path:
    return out / "runs" / f"{arm}-{seed}"


def pilot_tasks(plan: Plan) -> list[Task]:
    return [(PILOT.name, s) for s in plan.pilot_seed_list()]


def arm_tasks(plan: Plan) -> list[Task]:
    """Every arm's runs: the baseline's seeds first (every verdict and criterion reads them),
    then the other arms seed by seed (so that seed 0 of every arm comes before seed 1)."""
    others = [arm for arm in plan.chosen if arm.name != BASELINE]
    return [(BASELINE, seed) for seed in range(plan.seeds)] + [
        (arm.name, seed) for seed in range(plan.seeds) for arm in others
    ]


def measures_path(out: Path, task: Task) -> Path:
    return out / "measures" / f"{task[0]}-{task[1]}.json"


def measured(out: Path, task: Task) -> bool:
    """Whether the run's measures are saved: then it is done, with or without its folder."""
    return measures_path(out, task).is_file()


def finished(out: Path, plan: TrainingPlan, task: Task) -> bool:
    """Whether the run has its last checkpoint (at the last whole rollout, which may pass
    ``plan.timesteps``: 501,760 for 500k steps of 2,048)."""
    folder = run_dir(out, *task)
    steps = list_checkpoints(folder) if folder.is_dir() else {}
    return bool(steps) and max(steps) >= plan.timesteps


def train_config(plan: TrainingPlan, arm: Arm, seed: int) -> TrainConfig:
    return TrainConfig(
        algo=arm.algo,
        env_id=plan.env_id,
        total_timesteps=plan.timesteps,
        seed=seed,
        n_envs=plan.n_envs,
        num_steps=plan.num_steps,
        checkpoint_every=max(1, plan.timesteps // CHECKPOINTS),
        advice_scale=arm.scale if arm.scale > 0 else 1.0,
        advice_offset=ADVICE_OFFSET if arm.advice is not AdviceKind.NONE else 0.0,
    )


def train_task(out: Path, plan: Plan, task: Task, deadline: float | None = None) -> Task:
    """Train one run (one torch thread), resuming it where it stopped: to the end, or until
    the wall clock (``time.time()``) passes ``deadline``, when it stops at a checkpoint."""
    if not finished(out, plan, task):
        arm = ARM_BY_NAME[task[0]]
        advice = None if arm.advice is AdviceKind.NONE else load_tree(advice_path(out, arm))
        folder = run_dir(out, *task)
        resume = folder.is_dir() and bool(list_checkpoints(folder))
        if folder.is_dir() and not resume:  # stopped before its first checkpoint: start over
            shutil.rmtree(folder)
        stop = None if deadline is None else partial(past_deadline, deadline)
        train(train_config(plan, arm, task[1]), advice, folder, should_stop=stop, resume=resume)
    return task


def past_deadline(deadline: float) -> bool:
    return time.time() > deadline


def train_tasks(
    out: Path, plan: Plan, tasks: list[Task], workers: Workers, deadline: float | None = None
) -> None:
    """Train the ``tasks`` neither finished nor measured (until ``deadline``, when given)."""
    todo = [t for t in tasks if not (measured(out, t) or finished(out, plan, t))]
    workers.map(partial(train_task, out, plan, deadline=deadline), todo)


def parse_tasks(plan: Plan, names: str) -> list[Task]:
    """``"n1-2,p1-10-0"`` as the plan's tasks (``arm-seed``; pilots too), in the order given.

    Raises:
        InputError: a name that is none of the plan's runs.
    """
    known = {f"{arm}-{seed}": (arm, seed) for arm, seed in [*pilot_tasks(plan), *arm_tasks(plan)]}
    wanted = [name.strip() for name in names.split(",") if name.strip()]
    unknown = [name for name in wanted if name not in known]
    if unknown or not wanted:
        raise InputError(
            f"--runs: {', '.join(unknown) or 'none given'} is not a run of this validation "
            f"(arm-seed, e.g. {next(iter(known))}); its runs: {', '.join(known)}"
        )
    return [known[name] for name in dict.fromkeys(wanted)]


def check_advice(out: Path, tasks: list[Task]) -> None:
    """Refuse to train an advised run before the pilots' brackets have made its advice.

    Raises:
        InputError: the advice file of one of the tasks' arms is missing.
    """
    for name, seed in tasks:
        arm = ARM_BY_NAME[name]
        if arm.advice is not AdviceKind.NONE and not advice_path(out, arm).is_file():
            raise InputError(
                f"{name}-{seed} trains on advice that is not made yet: the pilots must be "
                "trained and the brackets made first (run acv validate without --runs)"
            )


def bracket_paths(out: Path, plan: Plan) -> list[Path]:
    return [out / "brackets" / f"bracket_{b}.json" for b in range(plan.brackets)]


def make_brackets(out: Path, plan: Plan) -> list[TreeDocument]:
    """The evaluation brackets (made once from the finished pilots, then reloaded) and the
    advice files of bracket 0."""
    paths = bracket_paths(out, plan)
    if not all(p.is_file() for p in paths):
        paths[0].parent.mkdir(parents=True, exist_ok=True)
        for b, path in enumerate(paths):
            dump_tree(_bracket(out, plan, b), path)
    trees = [load_tree(p) for p in paths]
    _write_advice(out, trees[0])
    return trees


def _bracket(out: Path, plan: Plan, b: int) -> TreeDocument:
    """The teacher's tree over candidates sampled (``informative``) from pilot ``b mod k``'s
    deterministic policy, all draws from ``BRACKET_SEED0 + b``."""
    seeds = plan.pilot_seed_list()
    pilot = run_dir(out, PILOT.name, seeds[b % len(seeds)])
    return pilot_bracket(pilot, plan, BRACKET_SEED0 + b)


def pilot_bracket(pilot: Path, plan: BracketPlan, seed: int) -> TreeDocument:
    """The teacher's tree over ``plan.candidates`` candidates sampled (``informative``) from
    the pilot run's deterministic policy, every draw from ``seed``."""
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.trained import deterministic_policy, load_agent

    policy = deterministic_policy(load_agent(find_checkpoint(pilot)))
    rng = np.random.default_rng(seed)
    candidates = sample_informative(plan.env_id, plan.candidates, rng=rng, policy=policy)
    return teacher_bracket(plan.env_id, candidates, rng, p=plan.p, seed=seed, teacher=plan.teacher)


def advice_path(out: Path, arm: Arm) -> Path:
    return out / "advice" / f"{arm.advice.value}.json"


def _write_advice(out: Path, advice: TreeDocument) -> None:
    folder = out / "advice"
    if (folder / "inverted.json").is_file():
        return
    folder.mkdir(parents=True, exist_ok=True)
    dump_tree(advice, folder / "advice.json")
    dump_tree(replay_with_teacher(advice, "random"), folder / "shuffled.json")
    dump_tree(inverted(advice), folder / "inverted.json")


def inverted(advice: TreeDocument) -> TreeDocument:
    """The advice turned around: the same bracket judged by score ``1 - s``.

    Raises:
        InputError: the advice records no scores (a human's tree: there is no s to invert).
    """
    if advice.scores is None:
        raise InputError("inverted advice needs the teacher's scores in the advice tree")
    flipped = {cid: 1.0 - s for cid, s in advice.scores.items()}
    return replay(advice, ScoreJudge(flipped), f"{advice.judge}-inverted", scores=flipped)


def read_json(path: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads(path.read_text())
    return data
