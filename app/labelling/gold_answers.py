"""A participant's answers to their gold items (issue 28 §1): storing one on the labelling
hot path, and each participant's gold score.

Their answers give each participant's gold accuracy with a Clopper–Pearson interval
(:func:`engine.reliability.gold_interval`), which the qualification gate reads
(:mod:`app.labelling.quality`). Where each copy is placed is
:mod:`app.labelling.gold_placement`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

from sqlalchemy import (
    BindParameter,
    Connection,
    CursorResult,
    bindparam,
    case,
    func,
    select,
    update,
)
from sqlalchemy.orm import Session, aliased

from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import CrowdSettings, GoldAnswer, GoldItem, Label, Participant, as_utc, utcnow
from app.recruiting import seats
from engine.errors import InputError


@dataclass(frozen=True)
class GoldScore:
    """A participant's gold answers: ``right`` of ``asked``."""

    right: int
    asked: int


PID: BindParameter[int] = bindparam("pid")
_answered, _answered_item = aliased(GoldAnswer), aliased(GoldItem)
#: The participant's gold answers so far, and how many of them are right.
_ASKED = (
    select(func.count())
    .select_from(_answered)
    .where(_answered.participant_id == PID, _answered.winner.is_not(None))
    .scalar_subquery()
)
_RIGHT = (
    select(func.count())
    .select_from(_answered)
    .join(_answered_item, _answered_item.id == _answered.gold_item_id)
    .where(_answered.participant_id == PID, _answered.winner == _answered_item.answer)
    .scalar_subquery()
)
#: The study's gate (NULL: none, or no open link).
_GATE = (
    select(CrowdSettings.gold_gate)
    .where(
        CrowdSettings.collection_kind == "study",
        CrowdSettings.collection_id == Participant.collection_id,
    )
    .scalar_subquery()
)
#: Everything a gold answer reads, in one ``SELECT`` after the lock: the participant's copy
#: of the item, the item, when they were last active, how many bracket matches they have
#: decided, their gold standing before this answer, and the study's gate.
_ANSWER_ROW = (
    select(
        GoldAnswer.position,
        GoldAnswer.winner,
        GoldItem.a,
        GoldItem.b,
        GoldItem.answer,
        Participant.last_active_at,
        Participant.created_at,
        select(func.count(Label.id)).where(Label.participant_id == PID).scalar_subquery(),
        _ASKED,
        _RIGHT,
        _GATE,
    )
    .join(GoldItem, GoldItem.id == GoldAnswer.gold_item_id)
    .join(Participant, Participant.id == GoldAnswer.participant_id)
    .where(GoldAnswer.participant_id == PID, GoldAnswer.gold_item_id == bindparam("item"))
)
#: Store the answer, only if still open (answers are written once).
_STORE = (
    update(GoldAnswer)
    .where(
        GoldAnswer.participant_id == PID,
        GoldAnswer.gold_item_id == bindparam("item"),
        GoldAnswer.winner.is_(None),
    )
    .values(winner=bindparam("winner"), response_ms=bindparam("ms"), answered_at=bindparam("now"))
)
_STORED = select(GoldAnswer.winner).where(
    GoldAnswer.participant_id == PID, GoldAnswer.gold_item_id == bindparam("item")
)
_TOUCH = update(Participant).where(Participant.id == PID).values(last_active_at=bindparam("now"))


@dataclass(frozen=True)
class GoldAnswered:
    """A participant's answer to a gold item: whether it was ``created`` (sending the same
    answer again is a no-op); ``done``, their decided bracket matches; ``standing``, their
    gold answers with this one; ``gate``, the study's (None: no gate)."""

    created: bool
    done: int
    standing: GoldScore
    gate: float | None


def answer(
    conn: Connection,
    *,
    participant_id: int,
    item_id: int,
    winner: int,
    response_ms: int | None = None,
) -> GoldAnswered:
    """Store a participant's answer to their copy of gold item ``item_id``, in one write
    transaction of four statements (the participant's labelling hot path calls it): take
    the participant's lock, read the item, their progress, their gold standing and the
    study's gate in one ``SELECT``, store the answer and mark them active. Their standing
    is the one read plus this answer: nobody else's answers, and no second read of theirs
    (issue 45 §7).

    Raises:
        NotFoundError: the participant has no such gold item.
        InputError: ``winner`` is not one of the pair.
        ConflictError: already answered the other way, or not due yet (fewer bracket
            matches decided than its position).
        MemberEndedError: they withdrew, or their time is over.
    """
    params = {"pid": participant_id, "item": item_id}
    with writing(conn):
        # the participant's lock, the one a label takes first too (app.labelling.flow): one
        # participant's answers are stored and counted one at a time, and none once they
        # withdrew or ran out of time
        seats.lock_in_time(conn, participant_id, utcnow())
        row = conn.execute(_ANSWER_ROW, params).one_or_none()
        if row is None:
            raise NotFoundError(f"gold item {item_id} is not one of this participant's")
        position, stored, a, b, right_answer, last_active, created, done, asked, right, gate = row
        if winner not in (a, b):
            raise InputError(f"winner must be {a} or {b}, got {winner}")
        standing = GoldScore(int(right), int(asked))
        if stored is not None:
            return _same_answer(item_id, winner, stored, done, standing, gate)
        # shown only once that many matches are decided: no answering ahead
        if position > done:
            raise ConflictError(
                f"gold item {item_id} is not due yet: it comes after {position} decided "
                f"matches, and {done} are decided"
            )
        now = utcnow()
        if response_ms is None:
            opened = last_active or created
            response_ms = max(0, round((now - as_utc(opened)).total_seconds() * 1000))
        values = params | {"winner": winner, "ms": response_ms, "now": now}
        if not cast(CursorResult[Any], conn.execute(_STORE, values)).rowcount:
            # answered meanwhile (the lock makes this unlikely): the same answer or a conflict
            return _same_answer(
                item_id, winner, conn.execute(_STORED, params).scalar(), done, standing, gate
            )
        conn.execute(_TOUCH, {"pid": participant_id, "now": now})
    after = GoldScore(standing.right + int(winner == right_answer), standing.asked + 1)
    return GoldAnswered(True, done, after, gate)


def _same_answer(
    item_id: int,
    winner: int,
    stored: int | None,
    done: int,
    standing: GoldScore,
    gate: float | None,
) -> GoldAnswered:
    if stored != winner:
        raise ConflictError(f"gold item {item_id} is already answered")
    return GoldAnswered(False, done, standing, gate)


def scores(
    session: Session, *, study_id: int, participant_id: int | None = None
) -> dict[int, GoldScore]:
    """Each participant's answered gold items: how many, and how many right (one
    participant's only, by the answers' primary key, with ``participant_id``)."""
    query = (
        select(
            GoldAnswer.participant_id,
            func.count(),
            func.sum(case((GoldAnswer.winner == GoldItem.answer, 1), else_=0)),
        )
        .join(GoldItem, GoldItem.id == GoldAnswer.gold_item_id)
        .where(GoldItem.study_id == study_id, GoldAnswer.winner.is_not(None))
        .group_by(GoldAnswer.participant_id)
    )
    if participant_id is not None:
        query = query.where(GoldAnswer.participant_id == participant_id)
    rows = session.execute(query)
    return {pid: GoldScore(int(right or 0), int(asked)) for pid, asked, right in rows}
