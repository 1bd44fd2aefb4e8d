"""Train and measure validation round 2's agents, resumably (docs/validation.md §6.3).

The folder holds ``round2.json`` (the :class:`Round2Plan`; another plan is refused),
``runs/<label>-<seed>/`` (ordinary training runs, resumed from their last checkpoint),
``brackets/`` (each advice bracket's teacher tree, with the teacher's scores, and on
Humanoid-v5 round 1's ``standing`` bracket), ``advice/`` (what the arms train on and the
verdict reads: the trees alone), ``measures/<label>-<seed>.json`` (each finished run's
per-candidate scores on every bracket and its ground truth) and ``states/<label>-<seed>.npz``
(its evaluation states). A run's label is its arm, then ``.b<bracket>`` for the arms that
train on one advice bracket (``p1-10.b2``); ``n1`` and the pilots have none.

As in round 1 (:mod:`engine.validation.runs`), everything but ``runs/`` is the round's small
state: a measured run is done, with or without its folder.
"""

from __future__ import annotations

import shutil
from dataclasses import asdict, dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from engine.pinned import pin_settings
from engine.pipeline import replay_with_teacher
from engine.rl.checkpoint import list_checkpoints
from engine.rl.runner import train
from engine.treefile import TreeDocument, dump_tree, load_tree
from engine.validation import round2
from engine.validation.design import ARM_BY_NAME, PILOT, AdviceKind, Arm, Role
from engine.validation.runs import (
    finished,
    inverted,
    past_deadline,
    pilot_bracket,
    run_dir,
    train_config,
)
from engine.validation.workers import Task, Workers

PLAN_FILE = "round2.json"
#: Round 2's arms beyond round 1's (:data:`engine.validation.design.ARMS`).
EXTRA_ARMS = {
    "p1-10-noisy": Arm("p1-10-noisy", "ppo-shaped", AdviceKind.NOISY, 10.0, Role.POSITIVE),
    "bipars-em-standing-shuffled": Arm(
        "bipars-em-standing-shuffled", "bipars-em", AdviceKind.STANDING_SHUFFLED, 1.0, Role.NEGATIVE
    ),
}
#: The noisy teacher's decision noise (B-Pref's), and the seed of the standing shuffled tree.
NOISE = 0.2
STANDING_SHUFFLE_SEED = round2.SHUFFLE_SEED0 + 100


@dataclass(frozen=True)
class Round2Plan:
    """Round 2 on one env: the declared design (:data:`engine.validation.round2.DESIGNS`),
    saved as ``round2.json`` and checked on resume. ``timesteps`` is the declared budget;
    only a smoke test sets less."""

    env_id: str
    timesteps: int
    teacher: str = "orthogonal"
    candidates: int = 16
    p: float = 0.9
    n_envs: int = 4
    num_steps: int = 512
    truth_episodes: int = 5
    standing_bracket: str | None = None
    """Round 1's ``standing`` bracket (Humanoid-v5): the standing-shuffled arm's tree."""

    @property
    def design(self) -> tuple[round2.ArmPlan, ...]:
        return round2.DESIGNS[self.env_id][0]

    @property
    def brackets(self) -> int:
        return 1 + max(b for arm in self.design for b in arm.brackets)


def arm_of(label: str) -> tuple[Arm, int | None]:
    """``"p1-10.b2"`` -> (the arm, bracket 2); ``"n1"`` -> (the arm, None)."""
    name, _, bracket = label.partition(".b")
    arm = EXTRA_ARMS.get(name) or ARM_BY_NAME[name]
    return arm, int(bracket) if bracket else None


def tasks(plan: Round2Plan) -> list[Task]:
    """Pilots first (they make the brackets), ``n1`` next (every criterion reads it), then
    every other run seed by seed, so that each arm's first seeds come early."""
    pilots = [(PILOT.name, round2.PILOT_SEED0 + k) for k in range(2)]
    n1 = next(arm for arm in plan.design if arm.name == "n1")
    base = [("n1", round2.EVAL_SEED0 + k) for k in range(n1.seeds)]
    labels = [f"{a.name}.b{b}" for a in plan.design if a.name != "n1" for b in a.brackets]
    seeds = max(a.seeds for a in plan.design if a.name != "n1")
    return pilots + base + [(lab, round2.EVAL_SEED0 + k) for k in range(seeds) for lab in labels]


def prepare(out: Path, plan: Round2Plan) -> None:
    """Write ``round2.json``, or check that ``out`` holds this same plan."""
    pin_settings(out / PLAN_FILE, asdict(plan), "a round 2 validation", normalize=lambda s: s)


def advice_file(out: Path, arm: Arm, bracket: int | None) -> Path:
    where = "" if arm.advice is AdviceKind.STANDING_SHUFFLED else f"-b{bracket}"
    return out / "advice" / f"{arm.advice.value}{where}.json"


def make_advice(out: Path, plan: Round2Plan) -> dict[str, TreeDocument]:
    """Each advice bracket's tree and controls (made once, from the finished pilots), and the
    brackets every run is measured on, by name (``b0``, ..., ``standing``)."""
    (out / "brackets").mkdir(parents=True, exist_ok=True)
    (out / "advice").mkdir(parents=True, exist_ok=True)
    found = {f"b{b}": _advice_bracket(out, plan, b) for b in range(plan.brackets)}
    if plan.standing_bracket is not None:
        found["standing"] = _standing(out, Path(plan.standing_bracket))
    return found


def _advice_bracket(out: Path, plan: Round2Plan, b: int) -> TreeDocument:
    path = out / "brackets" / f"advice-b{b}.json"
    if not path.is_file():
        pilot = run_dir(out, PILOT.name, round2.PILOT_SEED0 + b % 2)
        dump_tree(pilot_bracket(pilot, plan, round2.BRACKET_SEED0 + b), path)
    teacher_tree = load_tree(path)
    person = replace(teacher_tree, scores=None)  # what a person's tree holds
    kinds = {AdviceKind.ADVICE} | {
        arm_of(a.name)[0].advice for a in plan.design if b in a.brackets
    }  # the controls the design trains on this bracket
    for kind in sorted(kinds - {AdviceKind.STANDING_SHUFFLED}):
        target = out / "advice" / f"{kind.value}-b{b}.json"
        if not target.is_file():
            dump_tree(_control(kind, teacher_tree, plan, b), target)
    return person


def _control(
    kind: AdviceKind, teacher_tree: TreeDocument, plan: Round2Plan, b: int
) -> TreeDocument:
    """What an arm of bracket ``b`` trains on: the advice, its unrelated shuffled tree, the
    inverted tree or the noisy teacher's, each without the teacher's scores."""
    person = replace(teacher_tree, scores=None)
    if kind is AdviceKind.SHUFFLED:
        return round2.unrelated_tree(person, np.random.default_rng(round2.SHUFFLE_SEED0 + b))
    if kind is AdviceKind.INVERTED:
        return replace(inverted(teacher_tree), scores=None)
    if kind is AdviceKind.NOISY:
        noisy = replay_with_teacher(teacher_tree, plan.teacher, noise=NOISE)
        return replace(noisy, scores=None)
    return person


def _standing(out: Path, source: Path) -> TreeDocument:
    path = out / "brackets" / "standing.json"
    if not path.is_file():
        shutil.copyfile(source, path)
    standing = replace(load_tree(path), scores=None)
    target = out / "advice" / f"{AdviceKind.STANDING_SHUFFLED.value}.json"
    if not target.is_file():
        rng = np.random.default_rng(STANDING_SHUFFLE_SEED)
        dump_tree(round2.unrelated_tree(standing, rng), target)
    return standing


def train_task(out: Path, plan: Round2Plan, task: Task, deadline: float | None = None) -> Task:
    """Train one run (one torch thread), resuming it where it stopped."""
    if finished(out, plan, task):
        return task
    arm, bracket = arm_of(task[0])
    advice = None
    if arm.advice is not AdviceKind.NONE:
        advice = load_tree(advice_file(out, arm, bracket))
    folder = run_dir(out, *task)
    resume = folder.is_dir() and bool(list_checkpoints(folder))
    if folder.is_dir() and not resume:  # stopped before its first checkpoint: start over
        shutil.rmtree(folder)
    stop = None if deadline is None else partial(past_deadline, deadline)
    config = train_config(plan, arm, task[1])
    train(config, advice, folder, should_stop=stop, resume=resume)
    return task


def train_all(
    out: Path, plan: Round2Plan, todo: list[Task], workers: Workers, deadline: float | None
) -> None:
    """Train the tasks neither finished nor measured."""
    left = [t for t in todo if not (measured(out, t) or finished(out, plan, t))]
    workers.map(partial(train_task, out, plan, deadline=deadline), left)


def measures_path(out: Path, task: Task) -> Path:
    return out / "measures" / f"{task[0]}-{task[1]}.json"


def states_path(out: Path, task: Task) -> Path:
    return out / "states" / f"{task[0]}-{task[1]}.npz"


def measured(out: Path, task: Task) -> bool:
    """Whether the run's measures are saved: then it is done, with or without its folder."""
    return measures_path(out, task).is_file()
