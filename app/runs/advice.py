"""A run's advice, resolved from its source when the run is created: a finished
participant's Human Preference Tree, several pooled (:mod:`app.runs.pools`), or a simulated
teacher's tree over the study's bracket (the study's candidates and first round).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.labelling.participants import get_participant
from app.labelling.trees import participant_tree
from app.runs import pools
from app.runs.spec import AdviceSource, ParticipantAdvice, PooledAdvice, TeacherAdvice
from app.studies.service import engine_candidates_of, first_round, get_ready_study
from engine.bracket import Bracket
from engine.envs import env_model
from engine.errors import InputError
from engine.teachers import TEACHERS, make_teacher
from engine.tournament import play
from engine.treefile import TreeDocument, make_document


def resolve(
    session: Session,
    source: AdviceSource,
    *,
    study_id: int,
    tree_options: dict[str, Any] | None = None,
) -> tuple[pools.Pooled | None, TreeDocument | None]:
    """The run's pool (pooled advice only) and its advice tree (the pooled verdict for a
    pool; None without advice).

    Raises:
        InputError: a bad pool or teacher.
        NotFoundError, ConflictError: a participant not in the study, not finished or
            excluded, or a reliability-weighted pool whose reliabilities are all 0.
    """
    if isinstance(source, PooledAdvice):
        pooled = pools.pool_of(
            session,
            study_id=study_id,
            ids=_pool_ids(session, source, study_id=study_id),
            tree_options=tree_options,
            weighted=source.weighting == "reliability",
        )
        return pooled, pooled.verdict
    return None, advice_tree(session, study_id=study_id, source=source)


def _pool_ids(session: Session, source: PooledAdvice, *, study_id: int) -> list[int]:
    ids = pools.pool_ids(
        session,
        study_id=study_id,
        participant_ids=source.participant_ids,
        all_participants=source.participant_ids is None,
    )
    assert ids is not None  # a pool was asked for
    return ids


def advice_tree(
    session: Session, *, study_id: int, source: ParticipantAdvice | TeacherAdvice | None
) -> TreeDocument | None:
    """The advice a run of ``study_id`` would take from ``source`` (None: no advice)."""
    if isinstance(source, ParticipantAdvice):
        person = get_participant(session, participant_id=source.participant_id)
        if person.study_id != study_id:
            raise NotFoundError(f"participant {person.id} is not in study {study_id}")
        return participant_tree(session, participant_id=person.id)
    if isinstance(source, TeacherAdvice):
        return teacher_tree(session, study_id=study_id, teacher=source.teacher)
    return None


def teacher_tree(session: Session, *, study_id: int, teacher: str) -> TreeDocument:
    """A simulated teacher's tree over the study's bracket (as
    :func:`engine.pipeline.replay_with_teacher` makes it, without noise)."""
    if teacher not in TEACHERS:
        raise InputError(f"unknown teacher {teacher!r}: expected one of {', '.join(TEACHERS)}")
    study = get_ready_study(session, study_id=study_id)
    cands = engine_candidates_of(session, study_id=study_id)
    bracket = first_round(session, study_id=study_id)
    judge, scores = make_teacher(
        teacher,
        cands,
        env_model(study.env_id),
        noise=0.0,
        rng=np.random.default_rng([study.seed, 1]),
    )
    results = play(Bracket(bracket), {c.id: c for c in cands}, judge)
    return make_document(
        env_id=study.env_id,
        seed=study.seed,
        p=study.p,
        judge=teacher,
        candidates=cands,
        first_round=bracket,
        results=results,
        scores=scores,
    )
