"""Gold items (issue 28 §1): pairs with an objective answer, shown among the bracket's
matches at seeded positions, never part of the bracket or the tree.

Two kinds:

- ``pair``: two of the study's candidates, one of which the researcher says is right (a
  fallen and an upright posture in a study about standing, say). Shown like any match.
- ``instructed``: an instructed-response item, "choose the picture with the marker": the
  ``answer`` candidate is shown with a marker drawn on it.

Each participant gets a copy of every gold item the study had when they joined (a study's
items apply to people who join after they are added), at a position drawn from the study
seed and the participant: shown once that many bracket matches are decided, always before
the last one, on a seeded side. Their answers give each participant's gold accuracy with a
Clopper–Pearson interval (:func:`engine.reliability.gold_interval`), which the qualification
gate reads (:mod:`app.labelling.quality`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from sqlalchemy import (
    BindParameter,
    Connection,
    CursorResult,
    bindparam,
    case,
    delete,
    func,
    select,
    update,
)
from sqlalchemy.orm import Session, aliased

from app.core import atomic
from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import (
    Candidate,
    CrowdSettings,
    GoldAnswer,
    GoldItem,
    Label,
    Participant,
    Study,
    as_utc,
    utcnow,
)
from app.recruiting import seats
from app.studies.service import get_ready_study, get_study
from app.studies.sides import a_on_left
from engine.errors import InputError

GoldKind = Literal["pair", "instructed"]
GOLD_KINDS: tuple[GoldKind, ...] = ("pair", "instructed")
#: Most gold items a study may have: each one is a decision that is not a preference.
MAX_GOLD_ITEMS = 10
#: What an instructed-response item asks.
INSTRUCTED_PROMPT = "Check: choose the picture with the marker."
#: The round number that seeds the sides of gold items (bracket rounds start at 1; 0 is the
#: disagreement pairs').
SIDES_ROUND = -1


@dataclass(frozen=True)
class GoldScore:
    """A participant's gold answers: ``right`` of ``asked``."""

    right: int
    asked: int


@dataclass(frozen=True)
class GoldPair:
    """A gold item due now (:mod:`app.studies.gold`), shown before the next match."""

    item_id: int
    kind: str
    a: int
    b: int
    a_left: bool
    answer: int

    @property
    def left(self) -> int:
        return self.a if self.a_left else self.b

    @property
    def marked(self) -> int | None:
        """The candidate shown with the marker (instructed items only)."""
        return self.answer if self.kind == "instructed" else None

    @property
    def prompt(self) -> str | None:
        """What an instructed item asks; ``None`` for a pair, shown like any match."""
        return INSTRUCTED_PROMPT if self.kind == "instructed" else None


#: A participant's first unanswered gold item whose position has come.
_DUE = (
    select(GoldItem.id, GoldItem.kind, GoldItem.a, GoldItem.b, GoldAnswer.a_left, GoldItem.answer)
    .join(GoldItem, GoldItem.id == GoldAnswer.gold_item_id)
    .where(
        GoldAnswer.participant_id == bindparam("pid"),
        GoldAnswer.winner.is_(None),
        GoldAnswer.position <= bindparam("done"),
    )
    .order_by(GoldAnswer.position, GoldAnswer.gold_item_id)
    .limit(1)
)


def due_gold(conn: Connection, *, participant_id: int, done: int) -> GoldPair | None:
    """The participant's gold item to answer now that ``done`` bracket matches are decided
    (one indexed query: the participant's labelling hot path calls it)."""
    row = conn.execute(_DUE, {"pid": participant_id, "done": done}).one_or_none()
    return None if row is None else GoldPair(*row)


def list_items(session: Session, *, study_id: int) -> list[GoldItem]:
    """The study's gold items, oldest first.

    Raises:
        NotFoundError: no such study.
    """
    get_study(session, study_id=study_id)
    return list(
        session.scalars(
            select(GoldItem).where(GoldItem.study_id == study_id).order_by(GoldItem.id)
        ).all()
    )


def add_item(
    session: Session, *, study_id: int, kind: GoldKind, a: int, b: int, answer: int
) -> GoldItem:
    """Add a gold item to a ready study; participants who join from now on get it.

    Raises:
        NotFoundError, ConflictError: no such study, or it is not ready.
        InputError: an unknown kind, ``a == b``, a candidate that is not the study's, an
            answer that is neither ``a`` nor ``b``, or too many items.
    """
    study = get_ready_study(session, study_id=study_id)
    _check_item(session, study, kind, a, b, answer)
    item = GoldItem(study_id=study_id, kind=kind, a=a, b=b, answer=answer)
    with writing(session):  # counted with the item: concurrent adds never pass the limit
        if not atomic.take(
            session, Study.gold_item_count, Study.id == study_id, limit=MAX_GOLD_ITEMS
        ):
            raise InputError(f"a study has at most {MAX_GOLD_ITEMS} gold items")
        session.add(item)
    return item


def _check_item(session: Session, study: Study, kind: str, a: int, b: int, answer: int) -> None:
    if kind not in GOLD_KINDS:
        raise InputError(f"kind must be one of {', '.join(GOLD_KINDS)}, got {kind!r}")
    if a == b:
        raise InputError("a gold item needs two different candidates")
    for cid in (a, b):
        if session.get(Candidate, (study.id, cid)) is None:
            raise InputError(f"candidate {cid} is not one of study {study.id}'s candidates")
    if answer not in (a, b):
        raise InputError(f"answer must be {a} or {b}, got {answer}")


def get_item(session: Session, *, study_id: int, item_id: int) -> GoldItem:
    """The study's gold item, or :class:`NotFoundError`."""
    item = session.get(GoldItem, item_id)
    if item is None or item.study_id != study_id:
        raise NotFoundError(f"gold item {item_id} of study {study_id} not found")
    return item


def delete_item(session: Session, *, study_id: int, item_id: int) -> None:
    """Remove a gold item that nobody has answered yet.

    Raises:
        NotFoundError: no such item in this study.
        ConflictError: a participant answered it (their answers are kept).
    """
    item = get_item(session, study_id=study_id, item_id=item_id)
    answered = session.scalar(
        select(func.count())
        .select_from(GoldAnswer)
        .where(GoldAnswer.gold_item_id == item_id, GoldAnswer.winner.is_not(None))
    )
    if answered:
        raise ConflictError(f"gold item {item_id} has {answered} answers; it is kept")
    with writing(session):
        gone = session.execute(delete(GoldItem).where(GoldItem.id == item.id))
        if not cast(CursorResult[Any], gone).rowcount:  # a concurrent call removed it first
            raise NotFoundError(f"gold item {item_id} of study {study_id} not found")
        atomic.give_back(session, Study.gold_item_count, Study.id == study_id)
    session.expunge(item)


def positions(*, n_candidates: int, count: int, seed: int, participant_id: int) -> list[int]:
    """Where a participant's ``count`` gold items go: after how many bracket decisions each
    is shown, drawn from the study seed and the participant (not the researcher), from 1 to
    ``n - 2`` so that each comes after a first decision and before the last one."""
    rng = np.random.default_rng([seed, participant_id, 28])
    low, high = min(1, n_candidates - 2), max(0, n_candidates - 2)
    places = np.arange(low, high + 1)
    drawn = rng.choice(places, size=count, replace=count > len(places))
    return sorted(int(p) for p in drawn)


def stage_gold(session: Session, *, study: Study, people: Sequence[Participant]) -> None:
    """Give each of ``people`` (flushed, so with ids) a copy of the study's gold items, in
    the caller's transaction."""
    items = list_items(session, study_id=study.id)
    for person in people:
        places = positions(
            n_candidates=study.n_candidates,
            count=len(items),
            seed=study.seed,
            participant_id=person.id,
        )
        session.add_all(
            GoldAnswer(
                participant_id=person.id,
                gold_item_id=item.id,
                position=place,
                a_left=a_on_left(
                    seed=study.seed, participant_id=person.id, rnd=SIDES_ROUND, slot=item.id
                ),
            )
            for item, place in zip(items, places, strict=True)
        )


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
