"""Disagreement pairs after the bracket (issue 25 §5): pairs where the participant's own advice
and the study's no-advice baseline disagree most clearly (:mod:`engine.disagreement`).

A study with ``disagreement_pairs = k > 0`` asks each participant up to ``k`` such pairs once
their bracket is finished. The pairs are chosen on the first look after the bracket, from
the participant's tree (its heights are their advice's scores) and the baseline's return
stored with each candidate, leaving out pairs the bracket already played; they are stored
with the side each shows on the left. Undoing a bracket label drops the pairs still
unanswered: they are chosen again from the new tree once the bracket is finished again
(unless some pair was answered). They never enter the tree. A pair shows clips where a
match of the bracket would (:func:`app.labelling.open_matches.pair_shows_clips`), and its
answer records what was shown (``stimulus``). Their answers are exported with the labels
(:mod:`app.labelling.label_export`) and counted by the experiment verdict as matches of the
participant's advice (:func:`answered`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import AnsweredError, NotFoundError
from app.db import writing
from app.labelling.flow import MAX_RESPONSE_MS, check_stimulus
from app.labelling.participants import ParticipantKey, progress
from app.labelling.sides import a_on_left
from app.labelling.trees import participant_tree
from app.models import Candidate, DisagreementPair, Study, as_utc, utcnow
from app.recruiting import seats
from engine.disagreement import disagreement_pairs
from engine.errors import InputError
from engine.verdict import Pair, advice_scores

#: The round number that seeds the sides of disagreement pairs (bracket rounds start at 1).
SIDES_ROUND = 0


@dataclass(frozen=True)
class PairView:
    """A disagreement pair as shown: ``left`` and ``right`` candidate ids, ``position`` of
    ``total`` (from 0), and the answer (None while open)."""

    position: int
    total: int
    left: int
    right: int
    winner: int | None

    @classmethod
    def of(cls, row: DisagreementPair, total: int) -> PairView:
        left, right = (row.a, row.b) if row.a_left else (row.b, row.a)
        return cls(row.position, total, left, right, row.winner)


def pairs(session: Session, *, participant: ParticipantKey) -> list[PairView]:
    """The participant's pairs in order, chosen on the first call after their bracket
    (empty while it is unfinished, or when the study asks none)."""
    rows = _rows(session, participant.id)
    if not rows and progress(session, participant=participant).finished:
        rows = _create(session, participant)
    return [PairView.of(r, len(rows)) for r in rows]


def pending(session: Session, *, participant: ParticipantKey) -> PairView | None:
    """The first pair still to answer, or None."""
    return next((p for p in pairs(session, participant=participant) if p.winner is None), None)


def answer(
    session: Session,
    *,
    participant: ParticipantKey,
    position: int,
    winner: int,
    response_ms: int | None = None,
    stimulus: str = "still",
) -> tuple[PairView, bool]:
    """Store the answer to pair ``position`` and what its page showed (``stimulus``:
    ``still`` or ``clip``); returns the pair and whether it was new (sending the same answer
    again is a no-op).

    Raises:
        NotFoundError: the participant has no such pair (none yet: bracket unfinished).
        InputError: ``winner`` is not one of the pair, ``response_ms`` is out of range, or
            ``stimulus`` is neither ``still`` nor ``clip`` (or ``clip`` where the pair has no
            clips).
        ConflictError: the pair is already answered the other way.
        MemberEndedError: they withdrew, or their time is over.
    """
    if response_ms is not None and not 0 <= response_ms <= MAX_RESPONSE_MS:
        raise InputError(f"response_ms must be in 0..{MAX_RESPONSE_MS}, got {response_ms}")
    total = len(pairs(session, participant=participant))
    with writing(session):
        seats.lock_in_time(session, participant.id, utcnow(), after_finishing=True)
        row = session.get(
            DisagreementPair,
            (participant.id, position),
            with_for_update=True,
            populate_existing=True,
        )
        if row is None:
            raise NotFoundError(f"no disagreement pair {position} for this participant")
        if winner not in (row.a, row.b):
            raise InputError(f"winner must be {row.a} or {row.b}, got {winner}")
        check_stimulus(session, participant.study_id, (row.a, row.b), stimulus)
        created = row.winner is None
        if not created and row.winner != winner:
            raise AnsweredError(f"pair {position} is already answered: {row.winner} won")
        if created:
            _store_answer(session, row, winner, response_ms)
            row.stimulus = stimulus
    return PairView.of(row, total), created


def answered(session: Session, *, participant_id: int) -> tuple[Pair, ...]:
    """The participant's answered pairs as ``(a, b, winner)``, for the verdict."""
    rows = session.execute(
        select(DisagreementPair.a, DisagreementPair.b, DisagreementPair.winner)
        .where(
            DisagreementPair.participant_id == participant_id,
            DisagreementPair.winner.is_not(None),
        )
        .order_by(DisagreementPair.position)
    )
    return tuple((a, b, w) for a, b, w in rows if w is not None)


def _rows(session: Session, participant_id: int) -> list[DisagreementPair]:
    return list(
        session.scalars(
            select(DisagreementPair)
            .where(DisagreementPair.participant_id == participant_id)
            .order_by(DisagreementPair.position)
        )
    )


def _create(session: Session, participant: ParticipantKey) -> list[DisagreementPair]:
    """Choose and store the participant's pairs (another request may have done it first)."""
    study = session.get_one(Study, participant.study_id)
    if not study.disagreement_pairs:
        return []
    baseline = session.scalars(
        select(Candidate.baseline_return)
        .where(Candidate.study_id == study.id)
        .order_by(Candidate.id)
    ).all()
    if any(r is None for r in baseline):  # prepared without a baseline: nothing to ask
        return []
    tree = participant_tree(session, participant_id=participant.id)
    picked = disagreement_pairs(
        advice_scores(tree),
        np.array(baseline, dtype=float),
        k=study.disagreement_pairs,
        played=[(m.a, m.b) for m, _ in tree.matches],
    )
    rows = [
        DisagreementPair(
            participant_id=participant.id,
            position=k,
            a=a,
            b=b,
            a_left=a_on_left(
                seed=study.seed, participant_id=participant.id, rnd=SIDES_ROUND, slot=k
            ),
        )
        for k, (a, b) in enumerate(picked)
    ]
    try:
        with writing(session):
            session.add_all(rows)
    except IntegrityError:  # a concurrent request stored them first
        return _rows(session, participant.id)
    return rows


def _store_answer(
    session: Session, row: DisagreementPair, winner: int, response_ms: int | None
) -> None:
    """The answer, timed by the client, else since the pair was shown or the last answer."""
    now = utcnow()
    if response_ms is None:
        last = session.scalar(
            select(func.max(DisagreementPair.answered_at)).where(
                DisagreementPair.participant_id == row.participant_id
            )
        )
        opened = max(as_utc(t) for t in (row.shown_at, last) if t is not None)
        response_ms = max(0, round((now - opened).total_seconds() * 1000))
    row.winner, row.answered_at, row.response_ms = winner, now, response_ms
