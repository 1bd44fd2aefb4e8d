"""A participant's bracket: the next match, storing a label, undo, and the live bracket.

Each participant plays the study's whole bracket (:class:`engine.bracket.Bracket`): the
first-round matches exist from the invitation on, and storing a label creates the
next-round match as soon as both of its players are known. Writes for one participant are
serialised by updating their row first (a row lock on PostgreSQL; on SQLite the database's
single-writer lock, see :func:`app.db.writing`), and the UNIQUE ``labels.match_id``
constraint settles any race that gets through: a match has at most one label.

Undo: a participant may take back a label while no later match depends on it, i.e. iff the
next-round match containing its winner has no label yet. Their latest label always
qualifies (a later match that depends on it would have been labelled after it).
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import ScalarSelect, func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import writing
from app.models import BracketSlot, Label, Match, Participant, Study, as_utc, utcnow
from app.services.errors import ConflictError, NotFoundError
from app.services.participants import Progress, progress
from app.services.studies import first_round
from engine.bracket import Bracket, Results
from engine.errors import InputError

#: Longest response time stored (one day); a larger client value is bad input.
MAX_RESPONSE_MS = 24 * 3600 * 1000


@dataclass(frozen=True)
class NextMatch:
    """The participant's next match: "Round ``round`` of ``n_rounds``, match ``number`` of
    ``in_round``"."""

    match: Match
    n_rounds: int
    number: int
    in_round: int
    progress: Progress


@dataclass(frozen=True)
class LabelResult:
    """A stored label; ``created`` is ``False`` when the same label was already there."""

    label: Label
    match: Match
    created: bool
    progress: Progress


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


def next_match(session: Session, *, participant: Participant) -> NextMatch | None:
    """The earliest open match in (round, slot) order, or ``None`` when the bracket is done."""
    row = session.execute(
        select(Match, Study.n_candidates, _labels_done(participant.id))
        .join(Study, Study.id == participant.study_id).outerjoin(Label, Label.match_id == Match.id)
        .where(Match.participant_id == participant.id, Label.id.is_(None))
        .order_by(Match.round, Match.slot).limit(1)).one_or_none()
    if row is None:
        return None
    match, n, done = row
    size = 1 << (n - 1).bit_length()  # first-round slots x 2
    if match.round == 1:  # byes are not matches: count the real ones before this slot
        number = 1 + session.scalar(select(func.count()).where(
            BracketSlot.study_id == participant.study_id, BracketSlot.b.is_not(None),
            BracketSlot.slot < match.slot))
        in_round = n - size // 2
    else:
        number, in_round = match.slot + 1, size >> match.round
    return NextMatch(match, (n - 1).bit_length(), number, in_round, Progress(done, n - 1))


def _labels_done(participant_id: int) -> ScalarSelect[int]:
    return select(func.count(Label.id)).where(
        Label.participant_id == participant_id).scalar_subquery()


def submit_label(session: Session, *, participant: Participant, match_id: int, winner: int,
                 response_ms: int | None = None) -> LabelResult:
    """Store ``participant``'s decision of a match; sending the same one again is a no-op.

    Args:
        response_ms: time the participant took, measured by the client; when ``None`` it
            is estimated as the time since the match opened or since their previous label.

    Raises:
        NotFoundError: no such match among this participant's.
        InputError: ``winner`` did not play the match, or ``response_ms`` is out of range.
        ConflictError: the match is already decided the other way.
    """
    if response_ms is not None and not 0 <= response_ms <= MAX_RESPONSE_MS:
        raise InputError(f"response_ms must be in 0..{MAX_RESPONSE_MS}, got {response_ms}")
    try:
        with writing(session):
            return _submit(session, participant, match_id, winner, response_ms)
    except IntegrityError:  # a concurrent request stored this match's label first
        existing = _label_of(session, match_id)
        if existing is None:
            raise ConflictError("the bracket changed concurrently; try again") from None
        match = session.get(Match, match_id)
        return _same_or_conflict(session, participant, match, existing, winner)


def _submit(session: Session, participant: Participant, match_id: int, winner: int,
            response_ms: int | None) -> LabelResult:
    previous_activity = participant.last_active_at
    _lock(session, participant)
    row = session.execute(select(Match, Label).outerjoin(Label, Label.match_id == Match.id)
                          .where(Match.id == match_id)).one_or_none()
    if row is None or row[0].participant_id != participant.id:
        raise NotFoundError(f"match {match_id} not found among this participant's matches")
    match, existing = row
    if winner not in (match.a, match.b):
        raise InputError(f"winner {winner} did not play match {match_id} "
                         f"({match.a} vs {match.b})")
    if existing is not None:
        return _same_or_conflict(session, participant, match, existing, winner)
    if response_ms is None:
        opened = max(as_utc(t) for t in (match.created_at, previous_activity) if t is not None)
        response_ms = max(0, round((utcnow() - opened).total_seconds() * 1000))
    label = Label(match_id=match.id, participant_id=participant.id, winner=winner,
                  response_ms=response_ms)
    session.add(label)
    session.flush()
    done = progress(session, participant=participant)
    _advance(session, participant, match, winner, finished=done.finished)
    return LabelResult(label, match, True, done)


def _same_or_conflict(session: Session, participant: Participant, match: Match,
                      existing: Label, winner: int) -> LabelResult:
    if existing.winner != winner:
        raise ConflictError(f"match {match.id} is already decided: {existing.winner} won")
    return LabelResult(existing, match, False, progress(session, participant=participant))


def _lock(session: Session, participant: Participant) -> None:
    """Serialise this participant's writes (first statement of the write transaction)."""
    session.execute(update(Participant).where(Participant.id == participant.id)
                    .values(last_active_at=utcnow()))


def _label_of(session: Session, match_id: int) -> Label | None:
    return session.scalar(select(Label).where(Label.match_id == match_id))


def _advance(session: Session, participant: Participant, match: Match, winner: int, *,
             finished: bool) -> None:
    """After a label: open the next-round match once its other player is known, or mark the
    bracket finished. As in :class:`engine.bracket.Bracket`, the winners of slots ``2k`` and
    ``2k + 1`` meet in slot ``k`` of the next round, the even slot's winner as ``a``."""
    if finished:
        session.execute(update(Participant).where(Participant.id == participant.id)
                        .values(finished_at=utcnow()))
        return
    other = _winner_of(session, participant, match.round, match.slot ^ 1)
    if other is not None:
        a, b = (winner, other) if match.slot % 2 == 0 else (other, winner)
        session.add(Match(participant_id=participant.id, round=match.round + 1,
                          slot=match.slot // 2, a=a, b=b))


def _winner_of(session: Session, participant: Participant, rnd: int, slot: int) -> int | None:
    """Who won slot ``(rnd, slot)`` so far: a bye's player, a label's winner, or ``None``."""
    if rnd == 1:
        bye = session.get(BracketSlot, (participant.study_id, slot))
        if bye.b is None:
            return bye.a
    return session.scalar(select(Label.winner).join(Match, Match.id == Label.match_id).where(
        Match.participant_id == participant.id, Match.round == rnd, Match.slot == slot))


def results_of(session: Session, *, participant_id: int) -> dict[tuple[int, int], int]:
    """The participant's decided matches: ``(round, slot) -> winner``."""
    rows = session.execute(select(Match.round, Match.slot, Label.winner)
                           .join(Label, Label.match_id == Match.id)
                           .where(Match.participant_id == participant_id))
    return {(r, s): w for r, s, w in rows}


def undo_label(session: Session, *, participant: Participant,
               match_id: int | None = None) -> Match:
    """Take back a label (the participant's latest when ``match_id`` is ``None``); returns
    the match, open again.

    Raises:
        NotFoundError: ``match_id`` is not one of the participant's matches.
        ConflictError: nothing to undo, or a later match depends on the label (the
            next-round match containing its winner is decided).
    """
    with writing(session):
        _lock(session, participant)
        query = select(Label).where(Label.participant_id == participant.id)
        if match_id is not None:
            if (m := session.get(Match, match_id)) is None or m.participant_id != participant.id:
                raise NotFoundError(f"match {match_id} not found among this participant's "
                                    "matches")
            query = query.where(Label.match_id == match_id)
        label = session.scalar(query.order_by(Label.id.desc()).limit(1))
        if label is None:
            raise ConflictError("there is no label to undo")
        match = session.get(Match, label.match_id)
        later = session.scalar(select(Match).where(
            Match.participant_id == participant.id, Match.round == match.round + 1,
            Match.slot == match.slot // 2))
        if later is not None:
            if _label_of(session, later.id) is not None:
                raise ConflictError(f"cannot undo: round {later.round} match {later.a} vs "
                                    f"{later.b} already depends on it")
            session.delete(later)  # its players are no longer both known
        session.delete(label)
        session.execute(update(Participant).where(Participant.id == participant.id)
                        .values(finished_at=None))
    return match


def can_undo(session: Session, *, participant: Participant) -> bool:
    """Whether undoing the latest label (:func:`undo_label`) would succeed now."""
    last = session.scalar(select(Match).join(Label, Label.match_id == Match.id)
                          .where(Label.participant_id == participant.id)
                          .order_by(Label.id.desc()).limit(1))
    if last is None:
        return False
    return session.scalar(select(func.count(Label.id)).join(Match, Match.id == Label.match_id)
                          .where(Match.participant_id == participant.id,
                                 Match.round == last.round + 1,
                                 Match.slot == last.slot // 2)) == 0


def bracket_view(session: Session, *, participant: Participant) -> list[list[BracketCell]]:
    """The participant's whole bracket, round by round, as decided so far."""
    bracket = Bracket(first_round(session, study_id=participant.study_id))
    results: Results = results_of(session, participant_id=participant.id)
    ids = dict(((r, s), i) for r, s, i in session.execute(
        select(Match.round, Match.slot, Match.id).where(Match.participant_id == participant.id)))
    rounds: list[list[BracketCell]] = [[] for _ in range(bracket.n_rounds)]
    for (rnd, slot), (a, b) in bracket.slot_players(results).items():
        bye = rnd == 1 and b is None
        rounds[rnd - 1].append(BracketCell(rnd, slot, a, b, a if bye else results.get(
            (rnd, slot)), ids.get((rnd, slot)), bye))
    return rounds
