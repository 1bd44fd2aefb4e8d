"""``/api/surveys/{id}/crowd``: a survey's open link ``/q/<slug>`` and its options, with the
counts of respondents who joined, declined consent and completed (issue 14). Researcher
only."""

from __future__ import annotations

from fastapi import APIRouter, Request
from sqlalchemy.orm import Session

from app.http.deps import DbId, ResearcherDep, SessionDep
from app.models import SurveyCrowdSettings
from app.recruiting import service as recruiting
from app.recruiting.schemas import OpenLinkIn, SurveyCrowdOut
from app.surveys import crowd as survey_crowd

router = APIRouter(prefix="/surveys", tags=["surveys"])


def survey_crowd_out(
    request: Request, session: Session, row: SurveyCrowdSettings
) -> SurveyCrowdOut:
    url = survey_crowd.LINK.open_url(request.base_url, row.slug)
    fields = {
        k: getattr(row, k) for k in SurveyCrowdOut.model_fields if k not in ("url", "completed")
    }
    return SurveyCrowdOut.model_validate(
        fields | {"url": url, "completed": survey_crowd.completed(session, survey_id=row.survey_id)}
    )


@router.put("/{survey_id}/crowd")
def set_survey_crowd(
    survey_id: DbId, body: OpenLinkIn, request: Request, session: SessionDep, _: ResearcherDep
) -> SurveyCrowdOut:
    """Set the survey's open link ``/q/<slug>``: on or off, largest number of respondents,
    external id parameters, consent text, completion code and redirect URL."""
    row = recruiting.configure(session, survey_crowd.LINK, survey_id, body.options())
    return survey_crowd_out(request, session, row)


@router.get("/{survey_id}/crowd")
def get_survey_crowd(
    survey_id: DbId, request: Request, session: SessionDep, _: ResearcherDep
) -> SurveyCrowdOut:
    """The survey's open link, options and counts; 404 until they are set."""
    row = recruiting.configured(session, survey_crowd.LINK, survey_id)
    return survey_crowd_out(request, session, row)
