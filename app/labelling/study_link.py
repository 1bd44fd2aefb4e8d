"""A study's open link ``/s/<slug>`` as participants join it (issue 14): :data:`LINK`, the
study's kind of collection, and setting its options.

Joining, resuming, consent and the completion code are :mod:`app.recruiting.service`,
written once for studies and surveys; :data:`LINK` says what is a study's own: its table,
its path, that only a ready study takes people, and that a new participant gets their first
round of matches as they join (:func:`app.labelling.participants.stage_participants`). A
visitor carrying the study's first external parameter (``PROLIFIC_PID`` by default) who was
seen before resumes that participant: the ``members`` index ``UNIQUE (collection_kind,
collection_id, external_id)`` settles two first visits at once. The options themselves are
the study's (:mod:`app.studies.crowd`).
"""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.labelling.participants import stage_participants
from app.models import CrowdSettings, Participant, Study
from app.recruiting import service as recruiting
from app.recruiting.kinds import MemberKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import STUDY
from app.studies.crowd import CrowdOptions, StudyFullError, check_options
from app.studies.service import get_ready_study


class StudyKind:
    """A study's open link ``/s/<slug>`` (:class:`app.recruiting.kinds.MemberKind`): only a
    ready study takes people, and a new participant gets their first round as they join."""

    members = STUDY
    link = CrowdSettings
    prefix = "/s/"
    full_error: type[LinkFullError] = StudyFullError
    timed = True

    def check_collection(self, session: Session, collection_id: int) -> None:
        """Refuse a study that is not ready (:func:`get_ready_study`)."""
        get_ready_study(session, study_id=collection_id)

    def stage(self, session: Session, member: Participant) -> None:
        """Add a participant who joined, with their first round (the study is in the
        session: the join checked it is ready)."""
        study = session.get_one(Study, member.study_id)
        stage_participants(session, study=study, people=[member])


LINK: MemberKind[CrowdSettings, Participant] = StudyKind()


def configure(session: Session, *, study_id: int, options: CrowdOptions) -> CrowdSettings:
    """Set a ready study's open link and options (:func:`recruiting.configure`), the
    label-quality options checked first (:func:`app.studies.crowd.check_options`).

    Raises:
        InputError: a bad option, or a maximum below the participants already joined.
        NotFoundError, ConflictError: no such study, or it is not ready.
    """
    check_options(options)
    return recruiting.configure(session, LINK, study_id, options)
