"""A participant's bracket: the next match, storing a label, undo, and the live bracket.

Each participant plays the study's whole bracket (:class:`engine.bracket.Bracket`): the
first-round matches exist from the invitation on, and storing a label creates the
next-round match as soon as both of its players are known. The next match and storing a
label are the hot path, in :mod:`app.labelling.open_matches` and :mod:`app.labelling.flow`
(re-exported here). Writes for one participant are serialised by updating their row first
(a row lock on PostgreSQL; on SQLite the database's single-writer lock, see
:func:`app.db.writing`), and the UNIQUE ``labels.match_id`` constraint settles any race that
gets through: a match has at most one label.

Undo: a participant may take back a label while no later match depends on it, i.e. iff the
next-round match containing its winner has no label yet. Their latest label always
qualifies (a later match that depends on it would have been labelled after it). Never once
they have ended (withdrawn, out of time, stopped by the gate: their answers are kept as
they were) or answered anything after the bracket (a disagreement pair or the consistency
check was asked of this tree; the completion code may have been shown).
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import delete, exists, func, select, update
from sqlalchemy.orm import Session
from sqlalchemy.sql import ColumnElement

from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.labelling.flow import MAX_RESPONSE_MS, LabelResult, ParticipantKey, submit_label
from app.labelling.open_matches import NextMatch, next_match
from app.labelling.shape import shape_of
from app.models import (
    ConsistencyCheck,
    DisagreementPair,
    Label,
    Match,
    Member,
    Participant,
    utcnow,
)
from app.recruiting import seats
from engine.bracket import Bracket, Results

__all__ = [
    "MAX_RESPONSE_MS",
    "BracketCell",
    "LabelResult",
    "NextMatch",
    "ParticipantKey",
    "bracket_view",
    "can_undo",
    "next_match",
    "results_of",
    "submit_label",
    "undo_label",
]


@dataclass(frozen=True)
class BracketCell:
    """One slot of the live bracket; ``None`` where not yet known. A bye has ``b is None``
    and its player as ``winner``."""

    round: int
    slot: int
    a: int | None
    b: int | None
    winner: int | None
    match_id: int | None
    is_bye: bool


def _lock(session: Session, participant: ParticipantKey) -> None:
    """Serialise this participant's writes (first statement of the write transaction)."""
    session.execute(
        update(Participant).where(Participant.id == participant.id).values(last_active_at=utcnow())
    )


def _label_of(session: Session, match_id: int) -> Label | None:
    return session.scalar(select(Label).where(Label.match_id == match_id))


def results_of(session: Session, *, participant_id: int) -> dict[tuple[int, int], int]:
    """The participant's decided matches: ``(round, slot) -> winner``."""
    rows = session.execute(
        select(Match.round, Match.slot, Label.winner)
        .join(Label, Label.match_id == Match.id)
        .where(Match.participant_id == participant_id)
    )
    return {(r, s): w for r, s, w in rows}


def undo_label(
    session: Session, *, participant: ParticipantKey, match_id: int | None = None
) -> Match:
    """Take back a label (the participant's latest when ``match_id`` is ``None``); returns
    the match, open again.

    Raises:
        NotFoundError: ``match_id`` is not one of the participant's matches.
        ConflictError: nothing to undo, a later match depends on the label (the
            next-round match containing its winner is decided), or an answer after the
            bracket is stored.
        MemberEndedError: they withdrew, or their time is over.
    """
    with writing(session):
        seats.lock_in_time(session, participant.id, utcnow())
        _lock(session, participant)
        if session.scalar(select(_answered_after_the_bracket(participant.id))):
            raise ConflictError(
                "your answers after the bracket are stored, so the bracket can no longer change"
            )
        label = _label_to_undo(session, participant, match_id)
        match = session.get_one(Match, label.match_id)
        _drop_next_match(session, participant, match)
        session.delete(label)
        session.execute(update(Member).where(Member.id == participant.id).values(finished_at=None))
        # Disagreement pairs still to answer were chosen from the tree this undo changes;
        # answered ones stay (they are labels).
        session.execute(
            delete(DisagreementPair).where(
                DisagreementPair.participant_id == participant.id,
                DisagreementPair.winner.is_(None),
            )
        )
    return match


def _answered_after_the_bracket(participant_id: int) -> ColumnElement[bool]:
    """Whether a disagreement pair or the consistency check of the participant is answered."""
    pair = select(DisagreementPair.participant_id).where(
        DisagreementPair.participant_id == participant_id, DisagreementPair.winner.is_not(None)
    )
    checked = select(ConsistencyCheck.participant_id).where(
        ConsistencyCheck.participant_id == participant_id, ConsistencyCheck.winner.is_not(None)
    )
    return exists(pair) | exists(checked)


def _label_to_undo(session: Session, participant: ParticipantKey, match_id: int | None) -> Label:
    """The label of ``match_id``, or the participant's latest (404, 409 as :func:`undo_label`)."""
    query = select(Label).where(Label.participant_id == participant.id)
    if match_id is not None:
        if (m := session.get(Match, match_id)) is None or m.participant_id != participant.id:
            raise NotFoundError(f"match {match_id} not found among this participant's matches")
        query = query.where(Label.match_id == match_id)
    label = session.scalar(query.order_by(Label.id.desc()).limit(1))
    if label is None:
        raise ConflictError("there is no label to undo")
    return label


def _drop_next_match(session: Session, participant: ParticipantKey, match: Match) -> None:
    """Delete the next-round match that ``match``'s winner entered (its players are no longer
    both known), unless it is decided already (409)."""
    later = session.scalar(
        select(Match).where(
            Match.participant_id == participant.id,
            Match.round == match.round + 1,
            Match.slot == match.slot // 2,
        )
    )
    if later is None:
        return
    if _label_of(session, later.id) is not None:
        raise ConflictError(
            f"cannot undo: round {later.round} match {later.a} vs {later.b} already depends on it"
        )
    session.delete(later)


def can_undo(session: Session, *, participant: ParticipantKey) -> bool:
    """Whether undoing the latest label (:func:`undo_label`) would succeed now."""
    may_change = session.scalar(
        select(Member.id).where(
            Member.id == participant.id,
            seats.within_time(utcnow()),
            ~_answered_after_the_bracket(participant.id),
        )
    )
    if may_change is None:
        return False
    last = session.scalar(
        select(Match)
        .join(Label, Label.match_id == Match.id)
        .where(Label.participant_id == participant.id)
        .order_by(Label.id.desc())
        .limit(1)
    )
    if last is None:
        return False
    return (
        session.scalar(
            select(func.count(Label.id))
            .join(Match, Match.id == Label.match_id)
            .where(
                Match.participant_id == participant.id,
                Match.round == last.round + 1,
                Match.slot == last.slot // 2,
            )
        )
        == 0
    )


def bracket_view(session: Session, *, participant: ParticipantKey) -> list[list[BracketCell]]:
    """The participant's whole bracket, round by round, as decided so far."""
    bracket = Bracket(list(shape_of(session, participant.study_id).first_round))
    results: Results = results_of(session, participant_id=participant.id)
    ids = dict(
        ((r, s), i)
        for r, s, i in session.execute(
            select(Match.round, Match.slot, Match.id).where(Match.participant_id == participant.id)
        )
    )
    rounds: list[list[BracketCell]] = [[] for _ in range(bracket.n_rounds)]
    for (rnd, slot), (a, b) in bracket.slot_players(results).items():
        bye = rnd == 1 and b is None
        rounds[rnd - 1].append(
            BracketCell(
                rnd, slot, a, b, a if bye else results.get((rnd, slot)), ids.get((rnd, slot)), bye
            )
        )
    return rounds
