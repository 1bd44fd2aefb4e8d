"""``/api/studies/{id}/dashboard``: the researcher's live dashboard (issue 29 §1), polled by
the study page (``static/js/dashboard.js``). Researcher only.

An unchanged dashboard costs one aggregate ``SELECT`` and answers ``304 Not Modified`` to
``If-None-Match``; a changed one costs two (:mod:`app.labelling.dashboard`).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Header, Response

from app.http.deps import DbId, ResearcherDep, SessionDep
from app.labelling import dashboard
from app.studies.dashboard_schemas import DashboardOut, LiveCountsOut, LiveParticipantOut

router = APIRouter(prefix="/studies", tags=["crowd"])

_ETAG = {"ETag": {"description": "The dashboard's version.", "schema": {"type": "string"}}}


@router.get(
    "/{study_id}/dashboard",
    response_model=DashboardOut,
    responses={
        200: {"headers": _ETAG},
        304: {"description": "Unchanged since the ETag sent as If-None-Match.", "headers": _ETAG},
    },
)
def get_dashboard(
    study_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    if_none_match: Annotated[str | None, Header(max_length=2000)] = None,
) -> Response:
    """Participants joined, not started, labelling, finished and declined; each one's
    progress, median time per decision, flags and gold accuracy; labels per minute."""
    snap = dashboard.snapshot(session, study_id=study_id)
    headers = {"ETag": snap.etag, "Cache-Control": "private, no-cache"}
    if dashboard.etag_matches(if_none_match, snap.etag):
        return Response(status_code=304, headers=headers)
    body = dashboard_out(dashboard.dashboard(session, study_id=study_id, known=snap))
    # Written here: FastAPI would dump, validate and dump the model again (300 rows).
    return Response(body.model_dump_json(), media_type="application/json", headers=headers)


def dashboard_out(d: dashboard.Dashboard) -> DashboardOut:
    """The API body of a dashboard."""
    return DashboardOut(
        study_id=d.study_id,
        version=d.version,
        as_of=d.as_of,
        counts=LiveCountsOut(**vars(d.counts)),
        labels=d.labels,
        labels_last_minute=d.labels_last_minute,
        labels_per_minute=d.labels_per_minute,
        max_participants=d.max_participants,
        speed_threshold_ms=d.speed_threshold_ms,
        gold_gate=d.gold_gate,
        participants=[
            LiveParticipantOut(
                participant_id=p.id, **{k: v for k, v in vars(p).items() if k != "id"}
            )
            for p in d.participants
        ],
    )
