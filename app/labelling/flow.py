"""The participant's hot path: storing a label, in few statements (their next match is
:mod:`app.labelling.open_matches`).

Hundreds of people label at once (issue 16), so each request does as little as it can:

- a study's bracket shape (its size and first-round byes) never changes once the study is
  ready, so each process keeps it (:func:`app.labelling.shape.shape_of`) instead of querying
  it per request;
- the statements are built once, with bound parameters (:mod:`app.labelling.flow_sql`), and
  run on a plain connection (no statement construction, cache-key walk or ORM layer per
  request);
- storing a label is one write transaction of at most six statements: take the
  participant's lock, read the match, its label, the label count and the sibling slot's
  winner in one ``SELECT``, insert the label, open the next-round match or mark the bracket
  finished, and (on request) read the next open match, so that one round trip both stores
  a decision and brings the next one. The label that finishes the bracket also writes the
  study's webhook events (:mod:`app.labelling.events`; one indexed query when it has none).

Writes for one participant are serialised by updating their row first (a row lock on
PostgreSQL; on SQLite the database's single-writer lock, see :func:`app.db.writing`), and
the UNIQUE ``labels.match_id`` constraint settles any race that gets through.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, NoReturn

from sqlalchemy import Connection
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import AuthError, ConflictError, NotFoundError
from app.db import writing
from app.labelling import events, flow_sql
from app.labelling.gold_placement import due_gold
from app.labelling.open_matches import NextMatch, next_match, pair_shows_clips
from app.labelling.participants import ParticipantKey, Progress
from app.labelling.shape import BracketShape, shape_of
from app.labelling.sides import a_on_left, a_wins_tie
from app.models import STIMULUS_KINDS, as_utc, utcnow
from app.recruiting.members import STUDY
from app.recruiting.seats import MemberEndedError
from engine.errors import InputError

#: Longest response time stored (one day); a larger client value is bad input.
MAX_RESPONSE_MS = 24 * 3600 * 1000


@dataclass(frozen=True)
class LabelResult:
    """A stored label; ``created`` is ``False`` when the same label was already there.
    ``tie``: the participant could not tell and ``winner`` is the seeded coin's.
    ``next`` is the match to decide now (``None`` when finished or not asked for)."""

    match_id: int
    winner: int
    created: bool
    progress: Progress
    next: NextMatch | None = None
    tie: bool = False


def _connection(db: Session | Connection) -> Connection:
    return db.connection() if isinstance(db, Session) else db


@dataclass(frozen=True)
class Decision:
    """A participant's answer to a match: ``winner``, or ``tie`` ("can't tell"; the winner
    is then the seeded coin's, :func:`app.labelling.sides.a_wins_tie`); ``stimulus``: what
    the page showed, ``still`` or ``clip``."""

    match_id: int
    winner: int | None
    tie: bool
    response_ms: int | None
    stimulus: str = "still"

    def same_as(self, winner: int, tie: bool) -> bool:
        """Whether a stored label (``winner``, ``tie``) is this decision."""
        return tie if self.tie else not tie and winner == self.winner


def submit_label(
    db: Session | Connection,
    *,
    participant: ParticipantKey,
    match_id: int,
    winner: int | None,
    tie: bool = False,
    response_ms: int | None = None,
    with_next: bool = False,
    stimulus: str = "still",
) -> LabelResult:
    """Store ``participant``'s decision of a match; sending the same one again is a no-op.

    Args:
        winner: the preferred candidate; ``None`` with ``tie``.
        tie: the participant cannot tell (studies that allow it); the bracket advances by
            a seeded coin, recorded with the label.
        response_ms: time the participant took, measured by the client; when ``None`` it
            is estimated as the time since the match opened or since their previous write.
        with_next: also read the next open match, in the same transaction.
        stimulus: what the page showed: ``still``, or ``clip`` where both clips are rendered.

    Raises:
        AuthError: the participant no longer exists.
        NotFoundError: no such match among this participant's.
        InputError: ``winner`` did not play the match, ``response_ms`` is out of range,
            neither or both of ``winner`` and ``tie``, a tie the study does not allow, or
            ``clip`` where the pair has no clips.
        ConflictError: the match is already decided the other way, or a gold item is due
            before it.
    """
    if response_ms is not None and not 0 <= response_ms <= MAX_RESPONSE_MS:
        raise InputError(f"response_ms must be in 0..{MAX_RESPONSE_MS}, got {response_ms}")
    if (winner is None) != tie:
        raise InputError("give either a winner or tie: true, not both")
    shape = shape_of(db, participant.study_id)
    if tie and not shape.allow_ties:
        raise InputError('this study does not allow "can\'t tell": choose a picture')
    decision = Decision(match_id, winner, tie, response_ms, stimulus)
    try:
        with writing(db):  # type: ignore[type-var]  # a Session or a Connection, both fine
            return _submit(_connection(db), participant, shape, decision, with_next)
    except IntegrityError:  # a concurrent request stored this match's label first
        conn = _connection(db)
        existing = conn.execute(flow_sql.LABEL_WINNER, {"mid": match_id}).one_or_none()
        if existing is None:
            raise ConflictError("the bracket changed concurrently; try again") from None
        done = conn.execute(flow_sql.DONE_ONLY, {"pid": participant.id}).scalar_one()
        return _same_or_conflict(
            conn,
            participant,
            decision,
            (existing[0], existing[1]),
            Progress(done, shape.n - 1),
            with_next,
        )


def _submit(
    conn: Connection,
    participant: ParticipantKey,
    shape: BracketShape,
    decision: Decision,
    with_next: bool,
) -> LabelResult:
    now, pid, match_id = utcnow(), participant.id, decision.match_id
    if conn.execute(flow_sql.LOCK, {"pid": pid, "now": now}).rowcount == 0:
        _locked_out(conn, pid)
    row = conn.execute(flow_sql.MATCH_ROW, {"pid": pid, "mid": match_id}).one_or_none()
    if row is None:
        raise NotFoundError(f"match {match_id} not found among this participant's matches")
    rnd, slot, a, b, _, _, existing, was_tie, _, done, sibling = row
    if decision.winner is not None and decision.winner not in (a, b):
        raise InputError(f"winner {decision.winner} did not play match {match_id} ({a} vs {b})")
    check_stimulus(conn, participant.study_id, (a, b), decision.stimulus, shape)
    if existing is not None:
        return _same_or_conflict(
            conn, participant, decision, (existing, was_tie), Progress(done, shape.n - 1), with_next
        )
    if due_gold(conn, participant_id=pid, done=done) is not None:  # no skipping the checks
        raise ConflictError("answer the check pair shown before this match first")
    winner = _insert_label(conn, pid, shape, decision, row, now)
    progress = Progress(done + 1, shape.n - 1)
    if rnd == 1 and slot ^ 1 in shape.byes:
        sibling = shape.byes[slot ^ 1]
    if not progress.finished and sibling is not None:
        _open_next_round(conn, shape, pid, rnd, slot, winner, sibling)
    conn.execute(flow_sql.TOUCH, {"pid": pid, "now": now})
    if progress.finished:  # then webhook events, in this transaction (one query when none)
        conn.execute(flow_sql.FINISH, {"pid": pid, "now": now})
        events.finished(conn, participant=participant)
    return LabelResult(
        match_id,
        winner,
        True,
        progress,
        _next(conn, participant, progress, with_next),
        decision.tie,
    )


def _locked_out(conn: Connection, pid: int) -> NoReturn:
    """Say why the label's lock matched nobody.

    Raises:
        AuthError: no such participant.
        MemberEndedError: they withdrew, or their time is over (a time limit, or the gate).
    """
    row = conn.execute(flow_sql.LOCKED_OUT, {"pid": pid}).one_or_none()
    if row is None:
        raise AuthError(STUDY.unknown)
    if row.withdrawn_at is not None:
        raise MemberEndedError("you withdrew from this study: it takes no more labels from you")
    if row.gate_stopped_at is not None:
        raise MemberEndedError("this study has ended for you: it takes no more labels from you")
    raise MemberEndedError("your time for this study is over: it takes no more labels from you")


def _insert_label(
    conn: Connection,
    pid: int,
    shape: BracketShape,
    decision: Decision,
    match: Sequence[Any],
    now: datetime,
) -> int:
    """Store the label of an undecided match (a :data:`sql.MATCH_ROW`); returns who advances:
    the choice, or the seeded coin's after a tie."""
    rnd, slot, a, b, a_left, created_at, _, _, last_active = match[:9]
    winner = decision.winner
    if winner is None:  # a tie: the seeded coin decides who advances
        coin = a_wins_tie(seed=shape.seed, participant_id=pid, rnd=rnd, slot=slot)
        winner = a if coin else b
    response_ms = decision.response_ms
    if response_ms is None:
        opened = max(as_utc(t) for t in (created_at, last_active) if t is not None)
        response_ms = max(0, round((now - opened).total_seconds() * 1000))
    conn.execute(
        flow_sql.INSERT_LABEL,
        {
            "match_id": decision.match_id,
            "participant_id": pid,
            "winner": winner,
            "response_ms": response_ms,
            # a tie chose no side: it says nothing of position bias
            "chose_left": None if decision.tie else winner == (a if a_left else b),
            "tie": decision.tie,
            "stimulus": decision.stimulus,
        },
    )
    return winner


def _open_next_round(
    conn: Connection, shape: BracketShape, pid: int, rnd: int, slot: int, winner: int, sibling: int
) -> None:
    """Insert the next-round match of ``winner`` and the winner of the sibling slot."""
    pair = (winner, sibling) if slot % 2 == 0 else (sibling, winner)
    conn.execute(
        flow_sql.INSERT_MATCH,
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
    decision: Decision,
    stored: tuple[int, bool],
    progress: Progress,
    with_next: bool,
) -> LabelResult:
    winner, tie = stored
    if not decision.same_as(winner, tie):
        said = "can't tell" if tie else f"{winner} won"
        raise ConflictError(f"match {decision.match_id} is already decided: {said}")
    return LabelResult(
        decision.match_id,
        winner,
        False,
        progress,
        _next(conn, participant, progress, with_next),
        tie,
    )


def check_stimulus(
    db: Session | Connection,
    study_id: int,
    pair: tuple[int, int],
    stimulus: str,
    shape: BracketShape | None = None,
) -> None:
    """Refuse a ``stimulus`` the page of ``pair`` (a match, or a pair after the bracket, which
    shows clips where a match would) cannot have shown: :class:`InputError`."""
    if stimulus not in STIMULUS_KINDS:
        raise InputError(f'stimulus must be "still" or "clip", got {stimulus!r}')
    if stimulus == "clip" and not pair_shows_clips(db, study_id, *pair, shape=shape):
        raise InputError("this pair has no clips to show: its stimulus is a still")
