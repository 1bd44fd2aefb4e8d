"""Crowd recruiting of a tree-reading survey (issue 14): its open link ``/q/<slug>``.

Joining, resuming, consent and the completion code are :mod:`app.recruiting.service`, as for
studies; :data:`LINK` says what is a survey's own. A visitor carrying the survey's first
external parameter (``PROLIFIC_PID`` by default) who was seen before resumes that
respondent: ``UNIQUE (collection_kind, collection_id, external_id)`` on ``members`` settles
two first visits at once.
"""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.models import SurveyCrowdSettings, SurveyRespondent
from app.recruiting.kinds import MemberKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import SURVEY
from app.surveys.service import get_survey


class SurveyFullError(LinkFullError):
    """The survey's open link reached its largest number of respondents."""


class SurveyKind:
    """A survey's open link ``/q/<slug>`` (:class:`app.recruiting.kinds.MemberKind`): a
    survey takes people from its creation, and a new respondent starts with nothing more."""

    members = SURVEY
    link = SurveyCrowdSettings
    # /q/ (questionnaire), apart from the studies' /s/: each kind of link has its own table.
    prefix = "/q/"
    full_error: type[LinkFullError] = SurveyFullError
    timed = False

    def check_collection(self, session: Session, collection_id: int) -> None:
        """Refuse a survey that does not exist (:func:`get_survey`)."""
        get_survey(session, survey_id=collection_id)

    def stage(self, session: Session, member: SurveyRespondent) -> None:
        """Add a respondent who joined."""
        session.add(member)


LINK: MemberKind[SurveyCrowdSettings, SurveyRespondent] = SurveyKind()


def completed(session: Session, *, survey_id: int) -> int:
    """Respondents who came through the open link and answered every screen."""
    return (
        session.scalar(
            select(func.count(SurveyRespondent.id)).where(
                SurveyRespondent.survey_id == survey_id,
                SurveyRespondent.via_link.is_(True),
                SurveyRespondent.finished_at.is_not(None),
            )
        )
        or 0
    )
