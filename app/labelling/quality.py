"""Label quality of a study's participants (issues 14 and 28): position bias, speed, the
consistency check, gold accuracy with its interval and the qualification gate, the
reliability these give (each participant's: :mod:`app.labelling.participant_quality`), and
"can't tell" answers (their agreement with each other and with the simulated teachers:
:mod:`app.labelling.consensus`). Flags only: nothing is rejected automatically, unless the
researcher has the gate exclude (:func:`apply_gate`).

A tie ("can't tell") is neither agreement nor disagreement: it is left out of every
agreement and of position bias, and counted per participant."""

from __future__ import annotations

import statistics
from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db import writing
from app.labelling import gold_answers
from app.labelling.check import agreement_by_participant
from app.labelling.gate import GateStanding, below_gate
from app.labelling.gold_answers import GoldScore
from app.labelling.participant_quality import ParticipantQuality, is_fast
from app.labelling.participants import ParticipantKey
from app.labelling.study_link import LINK, configure
from app.models import CrowdSettings, Label, Match, Participant, utcnow
from app.recruiting import events, seats
from app.recruiting import service as recruiting
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS, CrowdOptions
from app.studies.service import get_study
from app.webhooks.outbox import Owner, webhook_ids
from engine import agreement


@dataclass(frozen=True)
class LabelRow:
    """One label with what quality and agreement need."""

    participant_id: int
    a: int
    b: int
    winner: int
    chose_left: bool | None
    response_ms: int | None
    tie: bool = False


@dataclass(frozen=True)
class StudyQuality:
    speed_threshold_ms: int
    bias: agreement.SideBias
    participants: list[ParticipantQuality]
    gold_gate: float | None = None


def label_rows(session: Session, *, study_id: int) -> list[LabelRow]:
    """Every label of the study, in label order."""
    rows = session.execute(
        select(
            Label.participant_id,
            Match.a,
            Match.b,
            Label.winner,
            Label.chose_left,
            Label.response_ms,
            Label.tie,
        )
        .join(Match, Match.id == Label.match_id)
        .join(Participant, Participant.id == Label.participant_id)
        .where(Participant.study_id == study_id)
        .order_by(Label.id)
    )
    return [LabelRow(*r) for r in rows]


@dataclass(frozen=True)
class _Known:
    """What a study knows of its participants beyond their labels."""

    threshold_ms: int
    gate: float | None
    consistent: dict[int, bool]
    gold: dict[int, GoldScore]


def _participant_quality(
    person: Participant, rows: list[LabelRow], known: _Known
) -> ParticipantQuality:
    sided = [r.chose_left for r in rows if r.chose_left is not None]
    times = [r.response_ms for r in rows if r.response_ms is not None]
    median = float(statistics.median(times)) if times else None
    return ParticipantQuality(
        person,
        agreement.side_bias(left=sum(sided), labels=len(sided)),
        median,
        is_fast(median, known.threshold_ms),
        known.consistent.get(person.id),
        known.gold.get(person.id, GoldScore(0, 0)),
        sum(r.tie for r in rows),
        known.gate,
    )


def _known(session: Session, study_id: int) -> _Known:
    settings = recruiting.settings(session, LINK, study_id)
    return _Known(
        settings.speed_threshold_ms if settings else DEFAULT_SPEED_THRESHOLD_MS,
        settings.gold_gate if settings else None,
        agreement_by_participant(session, study_id=study_id),
        gold_answers.scores(session, study_id=study_id),
    )


def quality(session: Session, *, study_id: int) -> StudyQuality:
    """Position bias, median response time, consistency, gold accuracy and ties, per
    participant and study."""
    get_study(session, study_id=study_id)
    known = _known(session, study_id)
    rows = label_rows(session, study_id=study_id)
    people = session.scalars(
        select(Participant).where(Participant.study_id == study_id).order_by(Participant.id)
    ).all()
    per = [
        _participant_quality(p, [r for r in rows if r.participant_id == p.id], known)
        for p in people
    ]
    sided = [r.chose_left for r in rows if r.chose_left is not None]
    return StudyQuality(
        known.threshold_ms, agreement.side_bias(left=sum(sided), labels=len(sided)), per, known.gate
    )


def configure_crowd(session: Session, *, study_id: int, options: CrowdOptions) -> CrowdSettings:
    """Set a study's open link and quality options (:func:`app.labelling.study_link.configure`),
    then apply a gate that excludes to the participants it flags already."""
    settings = configure(session, study_id=study_id, options=options)
    apply_gate(session, study_id=study_id)
    return settings


def apply_gate(session: Session, *, study_id: int, participant_id: int | None = None) -> list[int]:
    """Exclude the participants the gold gate flags, when the researcher has the gate
    exclude; returns who was newly excluded. Labels are kept. A participant the researcher
    decided on (excluded, or included again: ``exclusion_reason`` set) is left as decided.
    Whom the gate flags gets a ``participant.flagged`` webhook event, in this transaction.

    With ``participant_id`` (after a gold answer that the gate flags:
    :func:`gate_after_answer`), only their standing is read: one participant's gold
    answers, whatever the study's size (issue 45 §7).
    """
    settings = recruiting.settings(session, LINK, study_id)
    if settings is None or settings.gold_gate is None:
        return []
    if not settings.gate_excludes and not webhook_ids(session, Owner("study", study_id)):
        return []  # nobody to exclude, nobody to tell
    flagged = [s for s in _standings(session, study_id, participant_id, settings) if s.below_gate]
    newly = [s for s in flagged if settings.gate_excludes and _gated(s)]
    with writing(session):
        for s in newly:
            s.participant.excluded, s.participant.exclusion_reason = True, s.gate_reason
            _stop_mid_study(session, s, settings)
        for s in flagged:  # participant.flagged, once per participant (issue 29 §3)
            _gate_event(session, study_id, s)
    return [s.participant.id for s in newly]


def gate_after_answer(
    sessions: Callable[[], Session],
    person: ParticipantKey,
    standing: GoldScore,
    gate: float | None,
) -> None:
    """The gate after a participant's new gold answer, given their ``standing`` with it and
    the study's ``gate`` (both read in the answer's transaction): only when the gate flags
    them (rare) is there anything to do, :func:`apply_gate` to them in a session of its own;
    otherwise no statement at all (issue 45 §7)."""
    if below_gate(standing, gate):
        with sessions() as session:
            apply_gate(session, study_id=person.study_id, participant_id=person.id)


def _standings(
    session: Session, study_id: int, participant_id: int | None, settings: CrowdSettings
) -> list[GateStanding]:
    """Every participant's gate standing, or one participant's."""
    if participant_id is None:
        return [q.standing for q in quality(session, study_id=study_id).participants]
    person = session.get_one(Participant, participant_id)
    found = gold_answers.scores(session, study_id=study_id, participant_id=participant_id)
    return [GateStanding(person, found.get(participant_id, GoldScore(0, 0)), settings.gold_gate)]


def _gate_event(session: Session, study_id: int, q: GateStanding) -> None:
    data = {"flags": ["below_gate"], "reason": q.gate_reason, "excluded": q.participant.excluded}
    events.flagged(
        session, LINK, member_id=q.participant.id, owner_id=study_id, by="gold_gate", data=data
    )


#: The fewest failed gold items the gate stops a participant mid-study after (as platforms'
#: attention-check rules require: never on one slip).
STOP_AFTER_FAILED = 2


def _stop_mid_study(session: Session, q: GateStanding, link: CrowdSettings) -> None:
    """End an unfinished participant the gate excludes after enough failed gold items: time
    over now (the label path refuses them), seat given back, outcome ``failed_gate``."""
    person = q.participant
    if person.finished_at is None and q.gold.asked - q.gold.right >= STOP_AFTER_FAILED:
        now = utcnow()
        person.gate_stopped_at, person.deadline_at = now, now
        seats.free_seat(session, person, link, now)


def _gated(q: GateStanding) -> bool:
    return q.below_gate and q.participant.exclusion_reason is None
