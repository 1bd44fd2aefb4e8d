"""Agreement of a study's participants (issue 14): on the pairs they share (pairwise and its
mean, Krippendorff's alpha) and with the simulated teachers. A tie ("can't tell") is neither
agreement nor disagreement: it is left out."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from app.labelling.quality import LabelRow, label_rows
from app.studies.service import engine_candidates_of, get_study
from engine import agreement
from engine.envs import env_model
from engine.teachers import make_teacher

#: Teachers each participant is compared with.
COMPARED_TEACHERS = ("standing", "good")


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
    """Each participant's decided pairs (unordered) and winners, ties left out."""
    out: dict[int, dict[agreement.Pair, int]] = {}
    for r in rows:
        if r.tie:  # "can't tell" is neither agreement nor disagreement
            continue
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
