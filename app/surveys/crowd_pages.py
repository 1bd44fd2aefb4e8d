"""A survey's open link ``/q/<slug>`` (issue 14): consent, a respondent per new visitor
(rate-limited with the studies' links, :func:`app.recruiting.pages.admit`), "this survey is
full"; and the researcher's open-link form on the survey page (its context:
:func:`app.surveys.pages.crowd_context`).

``/q/`` (questionnaire) rather than the studies' ``/s/``: each kind of link has its own
table whose UNIQUE slug the database enforces, so neither path needs a look-up in the other.
"""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session

from app.core import auth
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, is_https, redirect
from app.models import SurveyCrowdSettings
from app.recruiting import pages as open_links
from app.recruiting import service as recruiting
from app.recruiting.links import LinkOptions, check_open, is_full
from app.recruiting.schemas import OpenLinkIn
from app.surveys import crowd as survey_crowd
from app.surveys import service as surveys
from app.surveys.api import RespondentCookie
from app.surveys.pages import RESPOND

router = APIRouter(route_class=PageRoute, include_in_schema=False)


def _name(session: Session, link: SurveyCrowdSettings) -> str:
    return surveys.get_survey(session, survey_id=link.survey_id).name


def _full(request: Request, session: Session, link: SurveyCrowdSettings) -> Response:
    return open_links.full(request, _name(session, link), survey_crowd.LINK)


def _enter(
    request: Request,
    session: Session,
    link: SurveyCrowdSettings,
    ids: dict[str, str],
    cookie: str | None,
) -> Response:
    """Resume a returning visitor, or make a respondent of a new one; "full" past the max."""
    person = recruiting.returning(session, survey_crowd.LINK, link=link, ids=ids, token=cookie)
    if person is None:
        try:
            person = open_links.admit(
                request, lambda: recruiting.join(session, survey_crowd.LINK, link=link, ids=ids)
            )
        except survey_crowd.SurveyFullError:
            return _full(request, session, link)
    response = redirect(RESPOND)
    auth.set_member_cookie(
        response, survey_crowd.LINK.members, token=person.token, secure=is_https(request)
    )
    return response


@router.get("/q/{slug}")
def open_link(
    slug: str, request: Request, session: SessionDep, cookie: RespondentCookie = None
) -> Response:
    """The consent page, or straight on to the survey; "full" past the maximum."""
    link = recruiting.open_link(session, survey_crowd.LINK, slug)
    ids = recruiting.external_ids(link, open_links.query(request))
    returning = recruiting.returning(session, survey_crowd.LINK, link=link, ids=ids, token=cookie)
    if returning is None:
        check_open(link, what="survey")
    if returning is None and is_full(link):
        return _full(request, session, link)
    if returning is None and link.consent_text:
        path = survey_crowd.LINK.open_path(link.slug)
        return open_links.consent(request, _name(session, link), link, path, ids)
    return _enter(request, session, link, ids, cookie)


@router.post("/q/{slug}", dependencies=[CsrfChecked])
def consent(
    slug: str,
    request: Request,
    session: SessionDep,
    fields: FormFields,
    cookie: RespondentCookie = None,
) -> Response:
    """Agree (a respondent is made) or decline (only the count of declines grows)."""
    link = recruiting.open_link(session, survey_crowd.LINK, slug)
    ids = recruiting.external_ids(link, fields)
    if fields.get("decision") != "agree":
        recruiting.decline(session, survey_crowd.LINK, link=link)
        return open_links.message(
            request, _name(session, link), "You declined", open_links.DECLINED
        )
    return _enter(request, session, link, ids, cookie)


@router.post("/surveys/{survey_id}/crowd", dependencies=[ResearcherPage, CsrfChecked])
def set_crowd(survey_id: DbId, session: SessionDep, fields: FormFields) -> Response:
    """Save the open-link form (validated like ``PUT /api/surveys/{id}/crowd``), then show
    the survey page's crowd section."""
    body = open_links.validated(OpenLinkIn, open_links.link_form(fields))
    options = LinkOptions(**{**body.model_dump(), "external_params": tuple(body.external_params)})
    recruiting.configure(session, survey_crowd.LINK, survey_id, options)
    return redirect(f"/surveys/{survey_id}#crowd")
