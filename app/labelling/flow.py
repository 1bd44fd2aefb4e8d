"""The participant's hot path: their next match, and storing a label, in few statements.

Hundreds of people label at once (issue 16), so each request does as little as it can:

- a study's bracket shape (its size and first-round byes) never changes once the study is
  ready, so each process keeps it (:func:`app.labelling.shape.shape_of`) instead of querying
  it per request;
- the statements are built once, with bound parameters, and run on a plain connection
  (no statement construction, cache-key walk or ORM layer per request);
- storing a label is one write transaction of at most six statements: take the
  participant's lock, read the match, its label, the label count and the sibling slot's
  winner in one ``SELECT``, insert the label, open the next-round match or mark the bracket
  finished, and (on request) read the next open match, so that one round trip both stores
  a decision and brings the next one.

Writes for one participant are serialised by updating their row first (a row lock on
PostgreSQL; on SQLite the database's single-writer lock, see :func:`app.db.writing`), and
the UNIQUE ``labels.match_id`` constraint settles any race that gets through.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import BindParameter, Connection, bindparam, func, insert, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, aliased

from app.core.errors import AuthError, ConflictError, NotFoundError
from app.db import writing
from app.labelling.shape import BracketShape, shape_of
from app.models import Label, Match, Participant, as_utc, utcnow
from app.recruiting.members import STUDY
from app.studies.participants import ParticipantKey, Progress
from app.studies.sides import a_on_left
from engine.errors import InputError

#: Longest response time stored (one day); a larger client value is bad input.
MAX_RESPONSE_MS = 24 * 3600 * 1000


@dataclass(frozen=True)
class OpenMatch:
    """A match whose two players are known and which has no label yet."""

    id: int
    round: int
    slot: int
    a: int
    b: int
    a_left: bool = True

    @property
    def left(self) -> int:
        """The candidate shown on the left."""
        return self.a if self.a_left else self.b


@dataclass(frozen=True)
class NextMatch:
    """The participant's next match: "Round ``round`` of ``n_rounds``, match ``number`` of
    ``in_round``"."""

    match: OpenMatch
    n_rounds: int
    number: int
    in_round: int
    progress: Progress


@dataclass(frozen=True)
class LabelResult:
    """A stored label; ``created`` is ``False`` when the same label was already there.
    ``next`` is the match to decide now (``None`` when finished or not asked for)."""

    match_id: int
    winner: int
    created: bool
    progress: Progress
    next: NextMatch | None = None


_PID: BindParameter[int] = bindparam("pid")
_MID: BindParameter[int] = bindparam("mid")
_DONE = select(func.count(Label.id)).where(Label.participant_id == _PID).scalar_subquery()
_OPEN = (
    select(Match.id, Match.round, Match.slot, Match.a, Match.b, Match.a_left)
    .outerjoin(Label, Label.match_id == Match.id)
    .where(Match.participant_id == _PID, Label.id.is_(None))
    .order_by(Match.round, Match.slot)
    .limit(1)
)
_OPEN_AND_DONE = _OPEN.add_columns(_DONE)
#: The first statement of a label's transaction: takes the participant's lock.
_LOCK = (
    update(Participant).where(Participant.id == _PID).values(finished_at=Participant.finished_at)
)
_sibling, _sibling_label = aliased(Match), aliased(Label)
#: The winner of the slot whose winner meets this match's (slots 2k and 2k + 1 pair up).
_SIBLING_WINNER = (
    select(_sibling_label.winner)
    .join(_sibling, _sibling.id == _sibling_label.match_id)
    .where(
        _sibling.participant_id == _PID,
        _sibling.round == Match.round,
        _sibling.slot == Match.slot + 1 - 2 * (Match.slot % 2),
    )
    .scalar_subquery()
)
_MATCH_ROW = (
    select(
        Match.round,
        Match.slot,
        Match.a,
        Match.b,
        Match.a_left,
        Match.created_at,
        Label.winner,
        Participant.last_active_at,
        _DONE,
        _SIBLING_WINNER,
    )
    .join(Participant, Participant.id == Match.participant_id)
    .outerjoin(Label, Label.match_id == Match.id)
    .where(Match.id == _MID, Match.participant_id == _PID)
)
_INSERT_LABEL, _INSERT_MATCH = insert(Label), insert(Match)
_TOUCH = update(Participant).where(Participant.id == _PID).values(last_active_at=bindparam("now"))
_FINISH = _TOUCH.values(finished_at=bindparam("now"))
_LABEL_WINNER = select(Label.winner).where(Label.match_id == _MID)
_DONE_ONLY = select(_DONE)


def _connection(db: Session | Connection) -> Connection:
    return db.connection() if isinstance(db, Session) else db


def next_match(
    db: Session | Connection, *, participant: ParticipantKey, done: int | None = None
) -> NextMatch | None:
    """The earliest open match in (round, slot) order, or ``None`` when the bracket is done.

    Args:
        done: the participant's label count when the caller knows it (saves a subquery).
    """
    shape = shape_of(db, participant.study_id)
    row = (
        _connection(db)
        .execute(_OPEN if done is not None else _OPEN_AND_DONE, {"pid": participant.id})
        .one_or_none()
    )
    if row is None:
        return None
    match = OpenMatch(*row[:6])
    number, in_round = shape.position(match.round, match.slot)
    return NextMatch(
        match,
        shape.n_rounds,
        number,
        in_round,
        Progress(row[6] if done is None else done, shape.n - 1),
    )


def submit_label(
    db: Session | Connection,
    *,
    participant: ParticipantKey,
    match_id: int,
    winner: int,
    response_ms: int | None = None,
    with_next: bool = False,
) -> LabelResult:
    """Store ``participant``'s decision of a match; sending the same one again is a no-op.

    Args:
        response_ms: time the participant took, measured by the client; when ``None`` it
            is estimated as the time since the match opened or since their previous write.
        with_next: also read the next open match, in the same transaction.

    Raises:
        AuthError: the participant no longer exists.
        NotFoundError: no such match among this participant's.
        InputError: ``winner`` did not play the match, or ``response_ms`` is out of range.
        ConflictError: the match is already decided the other way.
    """
    if response_ms is not None and not 0 <= response_ms <= MAX_RESPONSE_MS:
        raise InputError(f"response_ms must be in 0..{MAX_RESPONSE_MS}, got {response_ms}")
    shape = shape_of(db, participant.study_id)
    try:
        with writing(db):  # type: ignore[type-var]  # a Session or a Connection, both fine
            return _submit(
                _connection(db), participant, shape, match_id, winner, response_ms, with_next
            )
    except IntegrityError:  # a concurrent request stored this match's label first
        conn = _connection(db)
        existing = conn.execute(_LABEL_WINNER, {"mid": match_id}).scalar()
        if existing is None:
            raise ConflictError("the bracket changed concurrently; try again") from None
        done = conn.execute(_DONE_ONLY, {"pid": participant.id}).scalar_one()
        return _same_or_conflict(
            conn, participant, match_id, existing, winner, done, shape, with_next
        )


def _submit(
    conn: Connection,
    participant: ParticipantKey,
    shape: BracketShape,
    match_id: int,
    winner: int,
    response_ms: int | None,
    with_next: bool,
) -> LabelResult:
    now, pid = utcnow(), participant.id
    if conn.execute(_LOCK, {"pid": pid}).rowcount == 0:
        raise AuthError(STUDY.unknown)
    row = conn.execute(_MATCH_ROW, {"pid": pid, "mid": match_id}).one_or_none()
    if row is None:
        raise NotFoundError(f"match {match_id} not found among this participant's matches")
    rnd, slot, a, b, a_left, created_at, existing, last_active, done, sibling = row
    if winner not in (a, b):
        raise InputError(f"winner {winner} did not play match {match_id} ({a} vs {b})")
    if existing is not None:
        return _same_or_conflict(
            conn, participant, match_id, existing, winner, done, shape, with_next
        )
    if response_ms is None:
        opened = max(as_utc(t) for t in (created_at, last_active) if t is not None)
        response_ms = max(0, round((now - opened).total_seconds() * 1000))
    conn.execute(
        _INSERT_LABEL,
        {
            "match_id": match_id,
            "participant_id": pid,
            "winner": winner,
            "response_ms": response_ms,
            "chose_left": winner == (a if a_left else b),
        },
    )
    progress = Progress(done + 1, shape.n - 1)
    if rnd == 1 and slot ^ 1 in shape.byes:
        sibling = shape.byes[slot ^ 1]
    if not progress.finished and sibling is not None:
        _open_next_round(conn, shape, pid, rnd, slot, winner, sibling)
    conn.execute(_FINISH if progress.finished else _TOUCH, {"pid": pid, "now": now})
    return LabelResult(
        match_id, winner, True, progress, _next(conn, participant, progress, with_next)
    )


def _open_next_round(
    conn: Connection, shape: BracketShape, pid: int, rnd: int, slot: int, winner: int, sibling: int
) -> None:
    """Insert the next-round match of ``winner`` and the winner of the sibling slot."""
    pair = (winner, sibling) if slot % 2 == 0 else (sibling, winner)
    conn.execute(
        _INSERT_MATCH,
        {
            "participant_id": pid,
            "round": rnd + 1,
            "slot": slot // 2,
            "a": pair[0],
            "b": pair[1],
            "a_left": a_on_left(seed=shape.seed, participant_id=pid, rnd=rnd + 1, slot=slot // 2),
        },
    )


def _next(
    conn: Connection, participant: ParticipantKey, progress: Progress, with_next: bool
) -> NextMatch | None:
    if not with_next or progress.finished:
        return None
    return next_match(conn, participant=participant, done=progress.done)


def _same_or_conflict(
    conn: Connection,
    participant: ParticipantKey,
    match_id: int,
    existing: int,
    winner: int,
    done: int,
    shape: BracketShape,
    with_next: bool,
) -> LabelResult:
    if existing != winner:
        raise ConflictError(f"match {match_id} is already decided: {existing} won")
    progress = Progress(done, shape.n - 1)
    return LabelResult(
        match_id, existing, False, progress, _next(conn, participant, progress, with_next)
    )
