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
from app.recruiting.kinds import LinkKind
from app.recruiting.links import LinkFullError
from app.recruiting.members import SURVEY
from app.surveys.service import get_survey


class SurveyFullError(LinkFullError):
    """The survey's open link reached its largest number of respondents."""


LINK = LinkKind(
    members=SURVEY,
    link=SurveyCrowdSettings,
    # /q/ (questionnaire), apart from the studies' /s/: each kind of link has its own table.
    prefix="/q/",
    full_error=SurveyFullError,
    check_collection=lambda session, survey_id: get_survey(session, survey_id=survey_id),
    stage=lambda session, person: session.add(person),
)


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
