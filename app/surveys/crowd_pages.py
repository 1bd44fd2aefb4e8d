"""A survey's open link ``/q/<slug>`` (issue 14; the pages are
:func:`app.recruiting.pages.open_link_router`'s, as for studies), and the researcher's
open-link form on the survey page (its context: :func:`app.surveys.pages.crowd_context`).

``/q/`` (questionnaire) rather than the studies' ``/s/``: each kind of link has its own
table whose UNIQUE slug the database enforces, so neither path needs a look-up in the other.
"""

from __future__ import annotations

from fastapi import Request, Response

from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep, SettingsDep
from app.http.guards import ResearcherPage
from app.http.rendering import redirect
from app.recruiting import pages as recruiting_pages
from app.recruiting import service as recruiting
from app.recruiting.schemas import OpenLinkIn
from app.surveys import crowd
from app.surveys import service as surveys
from app.surveys.pages import RESPOND, render_survey_page
from engine.errors import InputError

router = recruiting_pages.open_link_router(
    recruiting_pages.LinkPages(
        kind=crowd.LINK,
        name_of=lambda session, survey_id: surveys.get_survey(session, survey_id=survey_id).name,
        next_path=lambda session, person: RESPOND,
    )
)


@router.post("/surveys/{survey_id}/crowd", dependencies=[ResearcherPage, CsrfChecked])
def set_crowd(
    survey_id: DbId,
    request: Request,
    session: SessionDep,
    settings: SettingsDep,
    fields: FormFields,
) -> Response:
    """Save the open-link form (validated like ``PUT /api/surveys/{id}/crowd``), then show
    the survey page's crowd section; a bad field shows the page again (422) with the form as
    it was sent and what is wrong."""
    try:
        body = recruiting_pages.validated(OpenLinkIn, recruiting_pages.link_form(fields))
        recruiting.configure(session, crowd.LINK, survey_id, body.options())
    except InputError as exc:
        again = {"crowd_form": recruiting_pages.form_echo(fields), "crowd_error": str(exc)}
        return render_survey_page(request, session, settings, survey_id, again, 422)
    return redirect(f"/surveys/{survey_id}#crowd")
