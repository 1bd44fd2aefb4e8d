"""An evaluation's evaluators: invited (``/v/<token>``) or joining its open link, each with
their own pairs, and their answers, each written once.

A new evaluator takes the next index of the evaluation's pair sequence, from one atomic
``UPDATE ... RETURNING`` (two joining at once get two indices), and their pairs are that
stretch of :func:`engine.evaluation.design.evaluator_pairs`: pairs over all runs, balanced,
with seeded sides and windows. A pair's stimuli are served under its opaque ``key``.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from typing import Literal

import numpy as np
from sqlalchemy import func, select, update
from sqlalchemy.orm import Session

from app.core.auth import new_token
from app.core.errors import ConflictError, NotFoundError
from app.core.limits import MAX_BATCH, check_text
from app.db import writing
from app.evaluations import gold
from app.evaluations.service import StimulusKind, get_evaluation, get_ready_evaluation
from app.labelling.participants import Progress
from app.models import (
    Evaluation,
    EvaluationPair,
    EvaluationStimulus,
    Evaluator,
    Member,
    utcnow,
)
from app.recruiting import seats
from engine.errors import InputError
from engine.evaluation.design import evaluator_pairs

Choice = Literal["left", "right", "tie"]
#: What an evaluator ticks to agree to share their answers (the open link's consent page and
#: the instructions page say it alike): the study dataset's ``evaluations`` config.
SHARE_LABEL = "I agree that my answers may be shared in a public dataset, under a pseudonym."


def add_evaluators(
    session: Session, *, evaluation_id: int, count: int = 1, name: str | None = None
) -> list[Evaluator]:
    """Invite ``count`` evaluators to a ready evaluation; their pairs exist.

    Raises:
        InputError: ``count`` outside 1..MAX_BATCH.
        NotFoundError, ConflictError: no such evaluation, or it is not ready.
    """
    if not 1 <= count <= MAX_BATCH:
        raise InputError(f"count must be in 1..{MAX_BATCH}, got {count}")
    check_text(name=name)
    get_ready_evaluation(session, evaluation_id=evaluation_id)
    with writing(session):
        people = [
            Evaluator(evaluation_id=evaluation_id, token=new_token(), name=name)
            for _ in range(count)
        ]
        for person in people:
            stage(session, person)
    return people


def stage(session: Session, person: Evaluator) -> None:
    """Add a new evaluator and their pairs, inside the caller's write transaction."""
    evaluation_id = person.evaluation_id
    index = session.execute(
        update(Evaluation)
        .where(Evaluation.id == evaluation_id)
        .values(evaluator_counter=Evaluation.evaluator_counter + 1)
        .returning(Evaluation.evaluator_counter)
    ).scalar_one()
    person.sequence_index = index - 1
    session.add(person)
    session.flush()
    evaluation = session.get(Evaluation, evaluation_id)
    assert evaluation is not None  # the UPDATE above found it
    session.add_all(_pairs(session, evaluation, person))


def _pairs(session: Session, evaluation: Evaluation, person: Evaluator) -> list[EvaluationPair]:
    """The evaluator's stretch of the pair sequence, with seeded windows, and their gold
    pairs among them (:mod:`app.evaluations.gold`); positions count both."""
    windows = _windows_per_slot(session, evaluation.id)
    n_runs = len(windows)
    plan = evaluator_pairs(
        n_runs, evaluation.pairs_per_evaluator, person.sequence_index, evaluation.seed
    )
    rng = np.random.default_rng([evaluation.seed, person.sequence_index, 1])
    real = [
        EvaluationPair(
            evaluator_id=person.id,
            key=secrets.token_urlsafe(16),
            a=int(a),
            b=int(b),
            window_a=int(rng.integers(windows[int(a)])),
            window_b=int(rng.integers(windows[int(b)])),
            a_left=bool(left),
            tie=False,
        )
        for a, b, left in zip(plan.a, plan.b, plan.a_left, strict=True)
    ]
    places = gold.gold_places(evaluation, person)
    extra = iter(gold.gold_pairs(evaluation, person, windows))
    ordered = []
    for i, pair in enumerate(real):
        ordered += [next(extra) for place in places if place == i]
        ordered.append(pair)
    ordered += list(extra)  # none: places are below the real pairs' count
    for position, pair in enumerate(ordered):
        pair.position = position
    return ordered


def _windows_per_slot(session: Session, evaluation_id: int) -> list[int]:
    rows = session.execute(
        select(EvaluationStimulus.slot, func.count())
        .where(EvaluationStimulus.evaluation_id == evaluation_id)
        .group_by(EvaluationStimulus.slot)
        .order_by(EvaluationStimulus.slot)
    ).all()
    return [int(n) for _, n in rows]


def list_evaluators(session: Session, *, evaluation_id: int) -> list[Evaluator]:
    """The evaluation's evaluators, oldest first."""
    get_evaluation(session, evaluation_id=evaluation_id)
    query = select(Evaluator).where(Evaluator.evaluation_id == evaluation_id)
    return list(session.scalars(query.order_by(Evaluator.id)))


def set_share_consent(session: Session, person: Evaluator, *, share: bool) -> bool:
    """Record whether the evaluator agrees that their answers may be shared in a public
    dataset under a pseudonym (the study dataset's ``evaluations`` config,
    :mod:`app.labelling.dataset`); an export follows their choice when it is made.

    Raises:
        MemberEndedError: they withdrew (:func:`app.recruiting.seats.set_share_consent`).
    """
    with writing(session):
        seats.set_share_consent(session, person, share=share)
    return person.share_consent


def progress(session: Session, *, evaluator_id: int) -> Progress:
    """How far the evaluator is."""
    done, total = session.execute(
        select(func.count(EvaluationPair.answered_at), func.count(EvaluationPair.position)).where(
            EvaluationPair.evaluator_id == evaluator_id
        )
    ).one()
    return Progress(int(done), int(total))


def next_pair(session: Session, *, evaluator_id: int) -> EvaluationPair | None:
    """The evaluator's first unanswered pair (``None``: all answered)."""
    return session.scalars(
        select(EvaluationPair)
        .where(EvaluationPair.evaluator_id == evaluator_id, EvaluationPair.answered_at.is_(None))
        .order_by(EvaluationPair.position)
        .limit(1)
    ).first()


def pair_by_key(session: Session, *, evaluator_id: int, key: str) -> EvaluationPair:
    """The evaluator's pair whose opaque key is ``key`` (nobody else's).

    Raises:
        NotFoundError: no such pair of theirs.
    """
    pair = session.scalars(
        select(EvaluationPair).where(
            EvaluationPair.evaluator_id == evaluator_id, EvaluationPair.key == key
        )
    ).first()
    if pair is None:
        raise NotFoundError("no such pair")
    return pair


@dataclass(frozen=True)
class Shown:
    """What the evaluator saw when answering: the stimulus kind (None: the pair's own,
    :func:`shown_kind`) and the reminder."""

    stimulus: str | None
    reminder: bool


def shown_kind(evaluation: Evaluation, pair: EvaluationPair) -> StimulusKind:
    """What ``pair`` is shown as: stills for an instructed gold pair (its marker is drawn on
    a still), clips once a clip evaluation's clips are rendered, stills until then."""
    clips = evaluation.stimulus == "clip" and evaluation.clips_ready
    return "clip" if clips and pair.gold_answer is None else "still"


def _stimulus(given: str | None, kind: StimulusKind) -> str:
    """The stimulus to record: ``given`` (stills are always on the page), else the pair's."""
    if given == "clip" and kind != "clip":
        raise InputError("this pair has no clips to show: it was shown as stills")
    return given or kind


def answer(
    session: Session,
    *,
    evaluator: Evaluator,
    key: str,
    choice: Choice,
    response_ms: int | None,
    shown: Shown,
) -> EvaluationPair:
    """Record the evaluator's answer to their pair ``key``: once; the same answer again is
    accepted, a different one is refused.

    Raises:
        NotFoundError: no such pair of theirs.
        InputError: ``clip`` for a pair shown as stills.
        ConflictError: the pair was answered otherwise already.
        MemberEndedError: they withdrew or ran out of time (checked by their lock).
    """
    pair = pair_by_key(session, evaluator_id=evaluator.id, key=key)
    evaluation = get_evaluation(session, evaluation_id=evaluator.evaluation_id)
    stimulus = _stimulus(shown.stimulus, shown_kind(evaluation, pair))
    tie = choice == "tie"
    chose_left = None if tie else choice == "left"
    winner = None if tie else (pair.a if chose_left == pair.a_left else pair.b)
    with writing(session):
        # the evaluator's lock, only while they may still act: their answers are stored one
        # at a time, so the last one sees every other and marks them finished
        seats.lock_in_time(session, evaluator.id, utcnow(), noun="evaluation")
        session.execute(
            update(EvaluationPair)
            .where(EvaluationPair.key == key, EvaluationPair.answered_at.is_(None))
            .values(
                winner=winner,
                tie=tie,
                chose_left=chose_left,
                response_ms=response_ms,
                stimulus=stimulus,
                reminder=shown.reminder,
                answered_at=utcnow(),
            )
        )
        if pair.gold_answer is not None:  # a gold answer: the gate reads the gold score
            gold.gate_after_answer(session, evaluator, evaluation)
        _finish_if_done(session, evaluator)
    session.refresh(pair)
    if (pair.winner, pair.tie) != (winner, tie):
        raise ConflictError("this pair was already answered otherwise")
    return pair


def _finish_if_done(session: Session, evaluator: Evaluator) -> None:
    """Mark the evaluator finished once no pair of theirs is left unanswered."""
    left = session.scalar(
        select(func.count())
        .select_from(EvaluationPair)
        .where(EvaluationPair.evaluator_id == evaluator.id, EvaluationPair.answered_at.is_(None))
    )
    if not left:
        session.execute(
            update(Member)
            .where(Member.id == evaluator.id, Member.finished_at.is_(None))
            .values(finished_at=utcnow())
        )
