"""Participants: invite tokens, their brackets' first matches, and progress."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.core.auth import new_token
from app.core.errors import NotFoundError
from app.core.limits import MAX_BATCH, check_text
from app.db import writing
from app.labelling.gold_placement import stage_gold
from app.labelling.sides import a_on_left
from app.models import Label, Match, Participant, Study
from app.recruiting import seats
from app.recruiting.members import STUDY
from app.studies.service import first_round, get_ready_study, get_study
from engine.bracket import Bracket
from engine.errors import InputError


class ParticipantKey(Protocol):
    """What the hot path needs to know of a participant (a row, or a cached key)."""

    @property
    def id(self) -> int: ...

    @property
    def study_id(self) -> int: ...


@dataclass(frozen=True)
class Progress:
    """Answers given (``done``) out of all a member is asked (``total``): a participant's
    labels out of the bracket's ``N - 1`` matches, an evaluator's pairs."""

    done: int
    total: int

    @property
    def finished(self) -> bool:
        return self.done >= self.total


@dataclass(frozen=True)
class ParticipantSummary:
    """A participant with their progress, for the researcher's lists."""

    participant: Participant
    progress: Progress


def invite_path(token: str) -> str:
    """The invite link's path (the page at ``/p/<token>`` sets the participant cookie)."""
    return STUDY.invite_path(token)


def invite_url(base_url: str, token: str) -> str:
    """The absolute invite link under ``base_url`` (e.g. ``http://127.0.0.1:8000``)."""
    return base_url.rstrip("/") + invite_path(token)


def add_participants(
    session: Session, *, study_id: int, count: int = 1, name: str | None = None
) -> list[Participant]:
    """Invite ``count`` new participants to a ready study; their first-round matches exist.

    Raises:
        InputError: ``count`` outside 1..:data:`MAX_BATCH`.
        NotFoundError, ConflictError: no such study, or it is not ready.
    """
    if not 1 <= count <= MAX_BATCH:
        raise InputError(f"count must be in 1..{MAX_BATCH}, got {count}")
    check_text(name=name)
    study = get_ready_study(session, study_id=study_id)
    people = [Participant(study_id=study_id, token=new_token(), name=name) for _ in range(count)]
    with writing(session):
        stage_participants(session, study=study, people=people)
    return people


def stage_participants(session: Session, *, study: Study, people: list[Participant]) -> None:
    """Add ``people`` and their opening matches to the session's transaction (the caller
    commits): every match known before any label, i.e. the first round, and any
    second-round match between two byes; each with its seeded left side."""
    opening = Bracket(first_round(session, study_id=study.id)).open_matches({})
    session.add_all(people)
    session.flush()  # assigns ids
    session.add_all(
        Match(
            participant_id=p.id,
            round=m.round,
            slot=m.slot,
            a=m.a,
            b=m.b,
            a_left=a_on_left(seed=study.seed, participant_id=p.id, rnd=m.round, slot=m.slot),
        )
        for p in people
        for m in opening
    )
    stage_gold(session, study=study, people=people)


def get_participant(session: Session, *, participant_id: int) -> Participant:
    """The participant, or :class:`NotFoundError`."""
    participant = session.get(Participant, participant_id)
    if participant is None:
        raise NotFoundError(f"participant {participant_id} not found")
    return participant


def set_exclusion(
    session: Session, *, participant_id: int, excluded: bool, reason: str | None = None
) -> Participant:
    """Exclude a participant from pooling and exports, or include them again; their labels
    are kept. The reason is recorded (a default one when none is given), and a gate that
    excludes leaves the participant as the researcher decided."""
    person = get_participant(session, participant_id=participant_id)
    check_text(reason=reason)
    default = "excluded by the researcher" if excluded else "included by the researcher"
    with writing(session):
        person.excluded, person.exclusion_reason = excluded, reason or default
    return person


def set_share_consent(session: Session, *, participant_id: int, share: bool) -> Participant:
    """Record whether the participant agrees that their labels may be shared in a public
    dataset under a pseudonym (:mod:`app.labelling.dataset`); they may change their mind,
    and an export follows their choice at the time it is made.

    Raises:
        MemberEndedError: they withdrew (:func:`app.recruiting.seats.set_share_consent`).
    """
    person = get_participant(session, participant_id=participant_id)
    with writing(session):
        seats.set_share_consent(session, person, share=share)
    return person


def n_matches(n_candidates: int) -> int:
    """Matches in a single-elimination bracket of ``n_candidates`` players."""
    return n_candidates - 1


def progress(session: Session, *, participant: ParticipantKey) -> Progress:
    """How far ``participant`` is through their bracket (one query)."""
    done = (
        select(func.count(Label.id)).where(Label.participant_id == participant.id).scalar_subquery()
    )
    n, labelled = session.execute(
        select(Study.n_candidates, done).where(Study.id == participant.study_id)
    ).one()
    return Progress(labelled, n_matches(n))


def list_participants(session: Session, *, study_id: int) -> list[ParticipantSummary]:
    """The study's participants with their progress, in invitation order."""
    study = get_study(session, study_id=study_id)
    done = dict(
        session.execute(
            select(Label.participant_id, func.count(Label.id))
            .join(Participant, Participant.id == Label.participant_id)
            .where(Participant.study_id == study_id)
            .group_by(Label.participant_id)
        ).all()
    )
    people = session.scalars(
        select(Participant).where(Participant.study_id == study_id).order_by(Participant.id)
    )
    total = n_matches(study.n_candidates)
    return [ParticipantSummary(p, Progress(done.get(p.id, 0), total)) for p in people]
