"""The open-link section of an evaluation's page (issue 41 §1: links like any study's): the
link ``/e/<slug>`` with its counts, and the form (``templates/_open_link_form.html``, as on a
study's and a survey's page) that saves it, validated like ``PUT /api/evaluations/{id}/crowd``.
An evaluation's link may set a time limit per evaluator (:data:`crowd.LINK` is timed).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session

from app.evaluations import crowd
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect
from app.recruiting import service as recruiting
from app.recruiting.kinds import open_url
from app.recruiting.links import LinkOptions
from app.recruiting.pages import link_form, validated, whole
from app.recruiting.schemas import OpenLinkIn

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])


def link_context(request: Request, session: Session, evaluation_id: int) -> dict[str, Any]:
    """What the evaluation page's "Crowd: open link" section shows: the saved link (``None``
    before the form is first saved, with the defaults in the form) and its URL."""
    row = recruiting.settings(session, crowd.LINK, evaluation_id)
    url = None if row is None else open_url(crowd.LINK, request.base_url, row.slug)
    return {"crowd": row, "crowd_defaults": LinkOptions(), "open_url": url}


def options(fields: dict[str, str]) -> LinkOptions:
    """The form's fields as the open link's options.

    Raises:
        InputError: a field that is not what ``PUT /api/evaluations/{id}/crowd`` takes, named.
    """
    limit = whole(fields, "time_limit_min") if fields.get("time_limit_min", "").strip() else None
    return validated(OpenLinkIn, link_form(fields) | {"time_limit_min": limit}).options()


@router.post("/evaluations/{evaluation_id}/crowd", dependencies=[CsrfChecked])
def set_crowd(evaluation_id: DbId, session: SessionDep, fields: FormFields) -> Response:
    """Save the open-link form, then the evaluation page's open-link section.

    Raises:
        InputError: a bad field (422 page with the message).
        NotFoundError, ConflictError: no such evaluation, or it cannot take evaluators yet.
    """
    recruiting.configure(session, crowd.LINK, evaluation_id, options(fields))
    return redirect(f"/evaluations/{evaluation_id}#crowd")
