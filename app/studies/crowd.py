"""Crowd recruiting of a study (issue 14): its open link ``/s/<slug>`` and label-quality
options.

Joining, resuming, consent and the completion code are :mod:`app.recruiting.service`,
written once for studies and surveys; :data:`LINK` says what is a study's own: its table,
its path, that only a ready study takes people, and that a new participant gets their first
round of matches as they join. A visitor carrying the study's first external parameter
(``PROLIFIC_PID`` by default) who was seen before resumes that participant: the ``members``
index ``UNIQUE (collection_kind, collection_id, external_id)`` settles two first visits at
once.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.orm import Session

from app.models import CrowdSettings, Participant, Study
from app.recruiting import service as recruiting
from app.recruiting.kinds import LinkKind
from app.recruiting.links import (
    DEFAULT_EXTERNAL_PARAMS,
    MAX_PARTICIPANTS,
    LinkFullError,
    LinkOptions,
    is_full,
)
from app.recruiting.members import STUDY
from app.studies.participants import stage_participants
from app.studies.service import get_ready_study
from engine.errors import InputError

__all__ = ["DEFAULT_EXTERNAL_PARAMS", "LINK", "MAX_PARTICIPANTS", "StudyFullError", "is_full"]
DEFAULT_SPEED_THRESHOLD_MS = 800


class StudyFullError(LinkFullError):
    """The open link reached its largest number of participants."""


@dataclass(frozen=True)
class CrowdOptions(LinkOptions):
    """What the researcher sets for a study's open link and label-quality checks."""

    consistency_check: bool = False
    speed_threshold_ms: int = DEFAULT_SPEED_THRESHOLD_MS
    gold_gate: float | None = None
    gate_excludes: bool = False
    gate_code: str | None = None


def _stage(session: Session, person: Participant) -> None:
    """Add a participant who joined, with their first round (the study is in the session:
    the join checked it is ready)."""
    stage_participants(session, study=session.get_one(Study, person.study_id), people=[person])


LINK = LinkKind(
    members=STUDY,
    link=CrowdSettings,
    prefix="/s/",
    full_error=StudyFullError,
    check_collection=lambda session, study_id: get_ready_study(session, study_id=study_id),
    stage=_stage,
    timed=True,
)


def configure(session: Session, *, study_id: int, options: CrowdOptions) -> CrowdSettings:
    """Set a ready study's open link and options (:func:`recruiting.configure`), the
    label-quality options checked here.

    Raises:
        InputError: a bad option, or a maximum below the participants already joined.
        NotFoundError, ConflictError: no such study, or it is not ready.
    """
    if not 0 <= options.speed_threshold_ms <= 600_000:
        raise InputError("speed_threshold_ms must be in 0..600000")
    if options.gold_gate is not None and not 0.0 <= options.gold_gate <= 1.0:
        raise InputError(f"gold_gate must be in [0, 1], got {options.gold_gate}")
    return recruiting.configure(session, LINK, study_id, options)
