"""The participant's next match: the earliest open one in (round, slot) order, with the gold
item due before it, in few indexed queries on a plain connection (the hot path, as
storing a label is: :mod:`app.labelling.flow`)."""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import Connection
from sqlalchemy.orm import Session

from app.labelling import flow_sql
from app.labelling.gold_placement import GoldPair, due_gold
from app.labelling.participants import ParticipantKey, Progress
from app.labelling.shape import BracketShape, shape_of


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
    ``in_round``"; ``gold``: a gold item to answer before it; ``allow_ties``: whether
    "can't tell" is an answer; ``clips``: the pair is shown as clips (both are rendered,
    and it is not a gold item)."""

    match: OpenMatch
    n_rounds: int
    number: int
    in_round: int
    progress: Progress
    gold: GoldPair | None = None
    allow_ties: bool = False
    clips: bool = False


def next_match(
    db: Session | Connection, *, participant: ParticipantKey, done: int | None = None
) -> NextMatch | None:
    """The earliest open match in (round, slot) order, with the gold item due before it if
    any, or ``None`` when the bracket is done.

    Args:
        done: the participant's label count when the caller knows it (saves a subquery).
    """
    shape = shape_of(db, participant.study_id)
    conn = db.connection() if isinstance(db, Session) else db
    row = conn.execute(
        flow_sql.OPEN if done is not None else flow_sql.OPEN_AND_DONE, {"pid": participant.id}
    ).one_or_none()
    if row is None:
        return None
    match = OpenMatch(*row[:6])
    decided = row[6] if done is None else done
    gold = due_gold(conn, participant_id=participant.id, done=decided)
    number, in_round = shape.position(match.round, match.slot)
    clips = gold is None and pair_has_clips(conn, shape, participant.study_id, match.a, match.b)
    return NextMatch(
        match,
        shape.n_rounds,
        number,
        in_round,
        Progress(decided, shape.n - 1),
        gold,
        shape.allow_ties,
        clips,
    )


def pair_has_clips(conn: Connection, shape: BracketShape, study_id: int, a: int, b: int) -> bool:
    """Whether both candidates' clips are rendered, in a study with clips (no query in
    another: a pair of stills)."""
    if not shape.clips:
        return False
    found = conn.execute(flow_sql.PAIR_CLIPS, {"sid": study_id, "a": a, "b": b}).scalar_one()
    return bool(found == 2)


def pair_shows_clips(
    db: Session | Connection, study_id: int, a: int, b: int, shape: BracketShape | None = None
) -> bool:
    """:func:`pair_has_clips`, looking the study's shape up where it is not at hand: the pairs
    asked after the bracket show clips exactly where a match of the bracket would."""
    conn = db.connection() if isinstance(db, Session) else db
    return pair_has_clips(conn, shape or shape_of(db, study_id), study_id, a, b)
