"""Simulated participants: a teacher plays invited brackets through the same service calls
a person's browser makes (for demos, tests and load checks)."""

from __future__ import annotations

import numpy as np
from sqlalchemy.orm import Session

from app.labelling.participants import add_participants
from app.labelling.service import next_match, submit_label
from app.models import Participant
from app.studies.service import engine_candidates_of, get_ready_study
from engine.envs import env_model
from engine.errors import InputError
from engine.teachers import TEACHERS, make_teacher
from engine.tournament import Judge


def play_bracket(session: Session, *, participant: Participant, judge: Judge) -> int:
    """Let ``judge`` decide each of the participant's open matches; returns labels sent."""
    by_id = {c.id: c for c in engine_candidates_of(session, study_id=participant.study_id)}
    sent = 0
    while (upcoming := next_match(session, participant=participant)) is not None:
        m = upcoming.match
        submit_label(
            session, participant=participant, match_id=m.id, winner=judge(by_id[m.a], by_id[m.b])
        )
        sent += 1
    return sent


def simulate(
    session: Session,
    *,
    study_id: int,
    teacher: str,
    participants: int = 1,
    noise: float = 0.0,
    seed: int = 0,
) -> list[Participant]:
    """Invite ``participants`` simulated participants and let ``teacher`` play each bracket.

    Args:
        teacher: a name from :data:`engine.teachers.TEACHERS`.
        noise: probability of flipping each decision (human error).
        seed: seeds the teacher's noise and coin flips.

    Raises:
        InputError: unknown teacher or bad noise.
        NotFoundError, ConflictError: no such study, or it is not ready.
    """
    if teacher not in TEACHERS:
        raise InputError(f"unknown teacher {teacher!r}: expected one of {', '.join(TEACHERS)}")
    if not 0.0 <= noise <= 1.0:
        raise InputError(f"noise must be in [0, 1], got {noise}")
    study = get_ready_study(session, study_id=study_id)
    cands = engine_candidates_of(session, study_id=study_id)
    judge, _ = make_teacher(
        teacher, cands, env_model(study.env_id), noise=noise, rng=np.random.default_rng(seed)
    )
    name = teacher if noise == 0 else f"{teacher}+noise{noise:g}"
    people = add_participants(
        session, study_id=study_id, count=participants, name=f"simulated {name}"
    )
    for person in people:
        play_bracket(session, participant=person, judge=judge)
    return people
