"""The optional consistency check (issue 14): after the bracket, one first-round pair comes
back with its sides swapped. It is not part of the bracket; its answer is compared with the
participant's label of that pair (:mod:`app.labelling.quality`). It shows clips where a match
of the bracket would (:func:`app.labelling.open_matches.pair_shows_clips`), and its answer
records what was shown (``stimulus``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import AnsweredError, ConflictError
from app.db import writing
from app.labelling.flow import check_stimulus
from app.models import (
    ConsistencyCheck,
    CrowdSettings,
    Label,
    Match,
    Participant,
    Study,
    as_utc,
    utcnow,
)
from app.recruiting import seats
from engine.errors import InputError


@dataclass(frozen=True)
class CheckPair:
    """The repeated pair as shown: ``left`` and ``right`` candidate ids."""

    match_id: int
    left: int
    right: int


def _wanted(session: Session, participant: Participant) -> bool:
    """Whether the study asks for a check and the participant finished the bracket."""
    enabled = session.scalar(
        select(CrowdSettings.consistency_check).where(
            CrowdSettings.study_id == participant.study_id
        )
    )
    return bool(enabled) and participant.finished_at is not None


def _create(session: Session, participant: Participant) -> ConsistencyCheck | None:
    """Pick one of the participant's first-round matches that they did not tie (seeded by
    the study seed and the participant) and store it with its sides swapped; ``None`` when
    they tied every one ("can't tell" has no answer to repeat)."""
    seed = session.execute(select(Study.seed).where(Study.id == participant.study_id)).scalar_one()
    firsts = session.scalars(
        select(Match)
        .join(Label, Label.match_id == Match.id)
        .where(Match.participant_id == participant.id, Match.round == 1, Label.tie.is_(False))
        .order_by(Match.slot)
    ).all()
    if not firsts:
        return None
    rng = np.random.default_rng([int(seed), participant.id])
    match = firsts[int(rng.integers(len(firsts)))]
    check = ConsistencyCheck(
        participant_id=participant.id, match_id=match.id, a_left=not match.a_left
    )
    try:
        with writing(session):
            session.add(check)
    except IntegrityError:  # another request created it first
        return session.get_one(ConsistencyCheck, participant.id)
    return check


def pending_pair(session: Session, *, participant: Participant) -> CheckPair | None:
    """The check still to answer (created on first call), or ``None`` when none is due."""
    if not _wanted(session, participant):
        return None
    check = session.get(ConsistencyCheck, participant.id) or _create(session, participant)
    if check is None or check.winner is not None:
        return None
    match = session.get_one(Match, check.match_id)
    left, right = (match.a, match.b) if check.a_left else (match.b, match.a)
    return CheckPair(match.id, left, right)


def answer(
    session: Session, *, participant: Participant, winner: int, stimulus: str = "still"
) -> None:
    """Store the check's answer and what its page showed (``stimulus``: ``still`` or
    ``clip``); sending the same answer again is a no-op.

    Raises:
        ConflictError: no check is due, or it was answered the other way.
        MemberEndedError: they withdrew, or their time is over.
        InputError: ``winner`` is not one of the pair, or ``stimulus`` is neither ``still``
            nor ``clip`` (or ``clip`` where the pair has no clips).
    """
    check = session.get(ConsistencyCheck, participant.id)
    if check is None or not _wanted(session, participant):
        raise ConflictError("no consistency check is due")
    match = session.get_one(Match, check.match_id)
    if winner not in (match.a, match.b):
        raise InputError(f"winner must be {match.a} or {match.b}")
    check_stimulus(session, participant.study_id, (match.a, match.b), stimulus)
    now = utcnow()
    with writing(session):  # the answer is read again under the write lock: two answers race
        seats.lock_in_time(session, participant.id, now, after_finishing=True)
        check = session.get_one(
            ConsistencyCheck, participant.id, with_for_update=True, populate_existing=True
        )
        if check.winner is not None:
            if check.winner != winner:
                raise AnsweredError("the consistency check is already answered the other way")
            return
        check.winner, check.answered_at, check.stimulus = winner, now, stimulus
        check.response_ms = max(0, round((now - as_utc(check.shown_at)).total_seconds() * 1000))


def agreement_by_participant(session: Session, *, study_id: int) -> dict[int, bool]:
    """Whether each answered check agrees with the participant's label of that pair."""
    rows = session.execute(
        select(ConsistencyCheck.participant_id, ConsistencyCheck.winner == Label.winner)
        .join(Label, Label.match_id == ConsistencyCheck.match_id)
        .join(Participant, Participant.id == ConsistencyCheck.participant_id)
        .where(Participant.study_id == study_id, ConsistencyCheck.winner.is_not(None))
    )
    return {pid: bool(same) for pid, same in rows}


__all__ = ["CheckPair", "agreement_by_participant", "answer", "pending_pair"]
