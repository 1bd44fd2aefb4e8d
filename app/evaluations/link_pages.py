"""The open-link section of an evaluation's page (issue 41 §1: links like any study's): the
link ``/e/<slug>`` with its counts, and the form (``templates/_open_link_form.html``, as on a
study's and a survey's page, posted to :mod:`app.evaluations.researcher_pages`) that saves it,
validated like ``PUT /api/evaluations/{id}/crowd``.
An evaluation's link may set a time limit per evaluator (:data:`crowd.LINK` is timed).
"""

from __future__ import annotations

from typing import Any

from fastapi import Request
from sqlalchemy.orm import Session

from app.evaluations import crowd
from app.recruiting import service as recruiting
from app.recruiting.kinds import open_url
from app.recruiting.links import LinkOptions
from app.recruiting.pages import link_form, validated, whole
from app.recruiting.schemas import OpenLinkIn


def link_context(request: Request, session: Session, evaluation_id: int) -> dict[str, Any]:
    """What the evaluation page's "Crowd: open link" section shows: the saved link (``None``
    before the form is first saved, with the defaults in the form) and its URL."""
    row = recruiting.settings(session, crowd.LINK, evaluation_id)
    url = None if row is None else open_url(crowd.LINK, request.base_url, row.slug)
    return {"crowd": row, "crowd_defaults": LinkOptions(), "open_url": url}


def link_options(fields: dict[str, str]) -> LinkOptions:
    """The form's fields as the open link's options.

    Raises:
        InputError: a field that is not what ``PUT /api/evaluations/{id}/crowd`` takes, named.
    """
    limit = whole(fields, "time_limit_min") if fields.get("time_limit_min", "").strip() else None
    return validated(OpenLinkIn, link_form(fields) | {"time_limit_min": limit}).options()
