"""``/api/surveys/{id}/crowd``: a survey's open link ``/q/<slug>`` and its options, with the
counts of respondents who joined, declined consent and completed (issue 14). Researcher
only."""

from __future__ import annotations

from app.recruiting.api import LinkApi, open_link_api_router
from app.recruiting.schemas import OpenLinkIn, SurveyCrowdOut
from app.surveys import crowd

router = open_link_api_router(
    LinkApi(
        kind=crowd.LINK,
        collections="surveys",
        tag="surveys",
        name="survey_crowd",
        body=OpenLinkIn,
        out=SurveyCrowdOut,
        counts=lambda session, row: {
            "completed": crowd.completed(session, survey_id=row.survey_id)
        },
    )
)
