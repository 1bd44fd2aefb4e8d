"""Agent evaluations: created from an experiment (its advised and baseline runs) or from any
two groups of runs of one env; what each evaluator is asked (issue 41 §1).

Creation checks what can be checked at once (the runs, their env and checkpoints, the
advisor), stores the slots and answers ``preparing``; the stimuli are rendered in the
background (:mod:`app.evaluations.stimuli`). Runs are put in slots in a seeded order, so a
slot says nothing of its run's arm or seed.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from typing import Literal

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import (
    Evaluation,
    EvaluationRun,
    ExperimentRole,
    Participant,
    Run,
    RunCheckpoint,
    Study,
    StudyStatus,
)
from app.runs import experiments
from app.runs.imported import is_imported
from engine.errors import InputError
from engine.practice import practice_pairs_error

EvaluatorKind = Literal["advisor", "others"]
StimulusKind = Literal["still", "clip"]

#: What each kind of evaluator is asked about every pair.
QUESTIONS: dict[str, str] = {
    "advisor": "Which one is closer to what you asked for?",
    "others": "Which agent follows the instruction better?",
}
#: Pairs per evaluator, and the advised agents' win rate the design is sized for, by default.
#: Power depends on the total of answers, not on how they are split (engine.evaluation.power:
#: 20 pairs is one stretch of the round-robin, each of 10 runs shown 4 times). 0.80 is the
#: smallest win rate 5 runs per arm detect at 80% power with round 1's run spread (about 10
#: evaluators); 0.65 cannot be, by any number of answers (power levels off near 0.31).
DEFAULT_PAIRS = 20
DEFAULT_TARGET = 0.8
#: Fewest runs per arm: a permutation test over fewer can never reject.
MIN_RUNS_PER_ARM = 2
MAX_RUNS_PER_ARM = 20
MAX_PAIRS = 200
#: Most instructed gold pairs per evaluator (each one is an answer that is not a judgement).
MAX_GOLD_PAIRS = 5


@dataclass(frozen=True)
class EvaluationSpec:
    """What a researcher asks for: the two groups of runs and the design.

    ``advised`` and ``baseline`` are run ids (at least :data:`MIN_RUNS_PER_ARM` each).
    """

    advised: tuple[int, ...]
    baseline: tuple[int, ...]
    evaluator_kind: EvaluatorKind = "others"
    show_bracket: bool = False
    stimulus: StimulusKind = "clip"
    pairs_per_evaluator: int = DEFAULT_PAIRS
    target_win_rate: float = DEFAULT_TARGET
    name: str | None = None
    experiment_id: int | None = None
    gold_pairs: int = 0
    gold_gate: float | None = None
    practice_pairs: int = 0


def experiment_arms(session: Session, *, experiment_id: int) -> tuple[tuple[int, ...], ...]:
    """An experiment's advised and baseline run ids (its pilots are left out).

    Raises:
        NotFoundError: no such experiment.
    """
    experiments.get_experiment(session, experiment_id=experiment_id)
    found = experiments.members(session, experiment_id=experiment_id)
    return tuple(
        tuple(run.id for role, run in found if role == wanted)
        for wanted in (ExperimentRole.ADVISED, ExperimentRole.BASELINE)
    )


def create_evaluation(session: Session, *, spec: EvaluationSpec) -> Evaluation:
    """Store an evaluation (``preparing``) and its slots; its stimuli render later.

    Raises:
        InputError: a bad design or too few runs per arm.
        NotFoundError: a run that does not exist.
        ConflictError: runs of different envs, without a checkpoint (an imported run's is
            its policy), or an advisor that is not one participant.
    """
    _check_design(spec)
    runs = _runs(session, spec.advised + spec.baseline)
    env_id = _one_env(session, runs)
    steps = _latest_steps(session, runs)
    advisor = _advisor(session, spec, runs[: len(spec.advised)])
    study = session.get(Study, runs[0].study_id)
    assert study is not None  # a run's study is never deleted before it
    evaluation = Evaluation(
        name=spec.name or _default_name(spec),
        env_id=env_id,
        experiment_id=spec.experiment_id,
        evaluator_kind=spec.evaluator_kind,
        question=QUESTIONS[spec.evaluator_kind],
        instructions=study.instructions,
        advisor_id=advisor,
        show_bracket=spec.show_bracket,
        stimulus=spec.stimulus,
        pairs_per_evaluator=spec.pairs_per_evaluator,
        target_win_rate=spec.target_win_rate,
        gold_pairs=spec.gold_pairs,
        gold_gate=spec.gold_gate,
        practice_pairs=spec.practice_pairs,
        seed=secrets.randbits(31),
        evaluator_counter=0,
        status=StudyStatus.PREPARING,
    )
    with writing(session):
        session.add(evaluation)
        session.flush()
        session.add_all(_slots(evaluation, spec, steps))
    return evaluation


def _check_design(spec: EvaluationSpec) -> None:
    if not 1 <= spec.pairs_per_evaluator <= MAX_PAIRS:
        raise InputError(
            f"pairs_per_evaluator must be in 1..{MAX_PAIRS}, got {spec.pairs_per_evaluator}"
        )
    if not 0.5 < spec.target_win_rate < 1:
        raise InputError(
            f"target_win_rate must be above 0.5 and below 1, got {spec.target_win_rate}"
        )
    for arm, ids in (("advised", spec.advised), ("baseline", spec.baseline)):
        if not MIN_RUNS_PER_ARM <= len(ids) <= MAX_RUNS_PER_ARM:
            raise InputError(
                f"{arm} needs {MIN_RUNS_PER_ARM} to {MAX_RUNS_PER_ARM} runs, got {len(ids)}"
            )
    if len(set(spec.advised + spec.baseline)) != len(spec.advised) + len(spec.baseline):
        raise InputError("a run is listed twice")
    if spec.show_bracket and spec.evaluator_kind != "advisor":
        raise InputError("show_bracket reminds the advisor of their bracket: advisor only")
    _check_quality(spec)


def _check_quality(spec: EvaluationSpec) -> None:
    """Gold pairs (0 to 5), the gate (a fraction in (0, 1], only with gold pairs) and
    practice pairs (0, or 2 to 5; :func:`engine.practice.practice_pairs_error`)."""
    if not 0 <= spec.gold_pairs <= MAX_GOLD_PAIRS:
        raise InputError(f"gold_pairs must be in 0..{MAX_GOLD_PAIRS}, got {spec.gold_pairs}")
    if spec.gold_gate is not None:
        if not 0 < spec.gold_gate <= 1:
            raise InputError(f"gold_gate must be above 0 and at most 1, got {spec.gold_gate}")
        if spec.gold_pairs == 0:
            raise InputError("gold_gate reads gold answers: set gold_pairs above 0")
    if (message := practice_pairs_error(spec.practice_pairs)) is not None:
        raise InputError(message)


def _runs(session: Session, ids: tuple[int, ...]) -> list[Run]:
    found = {r.id: r for r in session.scalars(select(Run).where(Run.id.in_(ids)))}
    if missing := [i for i in ids if i not in found]:
        raise NotFoundError(f"no run {missing[0]}")
    return [found[i] for i in ids]


def _one_env(session: Session, runs: list[Run]) -> str:
    study_ids = {r.study_id for r in runs}
    envs = set(session.scalars(select(Study.env_id).where(Study.id.in_(study_ids))))
    if len(envs) != 1:
        raise ConflictError(f"the runs are of different envs: {sorted(envs)}")
    return envs.pop()


def _latest_steps(session: Session, runs: list[Run]) -> dict[int, int]:
    """Each run's latest saved checkpoint. An imported run's one policy is stored when it is
    uploaded, at its declared steps (where its judged checkpoint is recorded too), so it is
    shown before it is judged."""
    rows = session.execute(
        select(RunCheckpoint.run_id, func.max(RunCheckpoint.step))
        .where(RunCheckpoint.run_id.in_([r.id for r in runs]))
        .group_by(RunCheckpoint.run_id)
    ).all()
    steps = {run_id: int(step) for run_id, step in rows}
    steps |= {r.id: int(r.timesteps) for r in runs if is_imported(r) and r.id not in steps}
    if without := [r.id for r in runs if r.id not in steps]:
        raise ConflictError(f"run {without[0]} has saved no checkpoint yet")
    return steps


def _advisor(session: Session, spec: EvaluationSpec, advised: list[Run]) -> int | None:
    """The participant whose tree trained every advised run, when they are to answer."""
    if spec.evaluator_kind != "advisor":
        return None
    people = {r.participant_id for r in advised}
    if len(people) != 1 or None in people:
        raise ConflictError(
            "the advised runs did not train on one participant's tree: "
            "choose evaluator_kind 'others'"
        )
    advisor = session.get(Participant, people.pop())
    assert advisor is not None  # runs cascade with their participant
    return advisor.id


def _default_name(spec: EvaluationSpec) -> str:
    if spec.experiment_id is not None:
        return f"Evaluation of experiment {spec.experiment_id}"
    return f"Evaluation of runs {', '.join(map(str, spec.advised))} against the others"


def _slots(
    evaluation: Evaluation, spec: EvaluationSpec, steps: dict[int, int]
) -> list[EvaluationRun]:
    """Every run in a seeded slot, so that slot numbers carry no arm or seed."""
    arms = [(run_id, True) for run_id in spec.advised] + [(r, False) for r in spec.baseline]
    order = np.random.default_rng(evaluation.seed).permutation(len(arms))
    return [
        EvaluationRun(
            evaluation_id=evaluation.id,
            slot=slot,
            run_id=arms[i][0],
            advised=arms[i][1],
            step=steps[arms[i][0]],
        )
        for slot, i in enumerate(order)
    ]


def get_evaluation(session: Session, *, evaluation_id: int) -> Evaluation:
    """The evaluation, or :class:`NotFoundError`."""
    evaluation = session.get(Evaluation, evaluation_id)
    if evaluation is None:
        raise NotFoundError(f"no evaluation {evaluation_id}")
    return evaluation


def get_ready_evaluation(session: Session, *, evaluation_id: int) -> Evaluation:
    """The evaluation, once its stills are rendered.

    Raises:
        NotFoundError: no such evaluation.
        ConflictError: still preparing, or failed.
    """
    evaluation = get_evaluation(session, evaluation_id=evaluation_id)
    if evaluation.status != StudyStatus.READY:
        raise ConflictError(f"evaluation {evaluation_id} is {evaluation.status.value}, not ready")
    return evaluation


def list_evaluations(session: Session, *, experiment_id: int | None = None) -> list[Evaluation]:
    """Every evaluation (of one experiment), newest first."""
    query = select(Evaluation).order_by(Evaluation.id.desc())
    if experiment_id is not None:
        query = query.where(Evaluation.experiment_id == experiment_id)
    return list(session.scalars(query))


def slots(session: Session, *, evaluation_id: int) -> list[EvaluationRun]:
    """The evaluation's slots, in slot order."""
    query = select(EvaluationRun).where(EvaluationRun.evaluation_id == evaluation_id)
    return list(session.scalars(query.order_by(EvaluationRun.slot)))


def preparing_ids(session: Session) -> list[int]:
    """Evaluations left ``preparing`` (by an earlier process, or queued)."""
    query = select(Evaluation.id).where(Evaluation.status == StudyStatus.PREPARING)
    return list(session.scalars(query))
