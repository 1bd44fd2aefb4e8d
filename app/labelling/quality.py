"""Label quality and agreement of a study's participants (issue 14): position bias, speed,
the consistency check and the reliability it gives, agreement on shared pairs, Krippendorff's
alpha, and agreement with the simulated teachers. Flags only: nothing is rejected
automatically."""

from __future__ import annotations

import statistics
from dataclasses import dataclass

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.labelling.check import agreement_by_participant
from app.models import Label, Match, Participant
from app.recruiting import service as recruiting
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS, LINK
from app.studies.service import engine_candidates_of, get_study
from engine import agreement
from engine.envs import env_model
from engine.reliability import Checks, competence
from engine.teachers import make_teacher

#: Position bias is flagged below this p-value of the binomial test.
BIAS_ALPHA = 0.05
#: Teachers each participant is compared with.
COMPARED_TEACHERS = ("standing", "good")


@dataclass(frozen=True)
class LabelRow:
    """One label with what quality and agreement need."""

    participant_id: int
    a: int
    b: int
    winner: int
    chose_left: bool | None
    response_ms: int | None


@dataclass(frozen=True)
class ParticipantQuality:
    participant: Participant
    bias: agreement.SideBias
    median_response_ms: float | None
    fast: bool
    consistency_agrees: bool | None

    @property
    def flags(self) -> list[str]:
        """``position_bias``, ``fast`` and ``inconsistent``, when they apply."""
        flags = []
        if self.bias.p_value is not None and self.bias.p_value < BIAS_ALPHA:
            flags.append("position_bias")
        if self.fast:
            flags.append("fast")
        if self.consistency_agrees is False:
            flags.append("inconsistent")
        return flags

    @property
    def checks(self) -> Checks:
        """The known-answer checks this participant answered: the consistency pair."""
        if self.consistency_agrees is None:
            return Checks()
        return Checks(consistent=int(self.consistency_agrees), consistency_asked=1)

    @property
    def reliability(self) -> float:
        """MACE competence from :attr:`checks` (:func:`engine.reliability.competence`): 0.25
        before any check, never from agreement with others (docs/method.md §2.13)."""
        return competence(self.checks)


@dataclass(frozen=True)
class StudyQuality:
    speed_threshold_ms: int
    bias: agreement.SideBias
    participants: list[ParticipantQuality]


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
        )
        .join(Match, Match.id == Label.match_id)
        .join(Participant, Participant.id == Label.participant_id)
        .where(Participant.study_id == study_id)
        .order_by(Label.id)
    )
    return [LabelRow(*r) for r in rows]


def _participant_quality(
    person: Participant, rows: list[LabelRow], threshold_ms: int, consistent: bool | None
) -> ParticipantQuality:
    sided = [r.chose_left for r in rows if r.chose_left is not None]
    times = [r.response_ms for r in rows if r.response_ms is not None]
    median = float(statistics.median(times)) if times else None
    return ParticipantQuality(
        person,
        agreement.side_bias(left=sum(sided), labels=len(sided)),
        median,
        median is not None and median < threshold_ms,
        consistent,
    )


def quality(session: Session, *, study_id: int) -> StudyQuality:
    """Position bias, median response time and consistency, per participant and study."""
    get_study(session, study_id=study_id)
    settings = recruiting.settings(session, LINK, study_id)
    threshold = settings.speed_threshold_ms if settings else DEFAULT_SPEED_THRESHOLD_MS
    rows = label_rows(session, study_id=study_id)
    checks = agreement_by_participant(session, study_id=study_id)
    people = session.scalars(
        select(Participant).where(Participant.study_id == study_id).order_by(Participant.id)
    ).all()
    per = [
        _participant_quality(
            p, [r for r in rows if r.participant_id == p.id], threshold, checks.get(p.id)
        )
        for p in people
    ]
    sided = [r.chose_left for r in rows if r.chose_left is not None]
    return StudyQuality(threshold, agreement.side_bias(left=sum(sided), labels=len(sided)), per)


@dataclass(frozen=True)
class TeacherAgreement:
    participant_id: int
    teacher: str
    labels: int
    agreement: float | None


@dataclass(frozen=True)
class StudyAgreement:
    participants: list[int]
    pairs: list[agreement.PairAgreement]
    mean: float | None
    alpha: float | None
    shared_pairs: int
    teachers: list[TeacherAgreement]


def choices(rows: list[LabelRow]) -> dict[int, dict[agreement.Pair, int]]:
    """Each participant's decided pairs (unordered) and winners."""
    out: dict[int, dict[agreement.Pair, int]] = {}
    for r in rows:
        out.setdefault(r.participant_id, {})[agreement.pair_key(r.a, r.b)] = r.winner
    return out


def _teachers(session: Session, study_id: int, rows: list[LabelRow]) -> list[TeacherAgreement]:
    study = get_study(session, study_id=study_id)
    cands = engine_candidates_of(session, study_id=study_id)
    by_id, model = {c.id: c for c in cands}, env_model(study.env_id)
    out = []
    for name in COMPARED_TEACHERS:
        judge, _ = make_teacher(name, cands, model, rng=np.random.default_rng(0))
        for pid, decided in choices(rows).items():
            same = sum(judge(by_id[a], by_id[b]) == w for (a, b), w in decided.items())
            out.append(
                TeacherAgreement(pid, name, len(decided), same / len(decided) if decided else None)
            )
    return out


def study_agreement(session: Session, *, study_id: int) -> StudyAgreement:
    """Pairwise agreement on shared pairs, its mean, Krippendorff's alpha (nominal), and
    each participant's agreement with each simulated teacher.

    Raises:
        NotFoundError: no such study.
    """
    get_study(session, study_id=study_id)
    rows = label_rows(session, study_id=study_id)
    decided = choices(rows)
    pairs = agreement.pairwise_agreement(decided)
    teachers = _teachers(session, study_id, rows) if rows else []
    return StudyAgreement(
        sorted(decided),
        pairs,
        agreement.mean_agreement(pairs),
        agreement.alpha_nominal(decided),
        len(agreement.shared_units(decided)),
        teachers,
    )
