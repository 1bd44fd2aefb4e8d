"""Survey pages: the researcher's list, new-survey form and survey page (stimuli, invite
links, open link, results), and the respondent's invite link and one-screen-at-a-time page.

The pages read through the service layer; their scripts (``static/js/survey*.js``) write
through the REST API (``/api/surveys``), so there are no form posts here (the open-link
form posts to :mod:`app.surveys.crowd_pages`).
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, RedirectResponse
from sqlalchemy.orm import Session

from app.http.deps import DbId, SessionDep, SettingsDep
from app.http.guards import ResearcherPage, enter_by_invite, page_member
from app.http.member_auth import RespondentCookie
from app.http.rendering import PageRoute, render
from app.models import Survey, SurveyRespondent
from app.recruiting import members
from app.recruiting import service as recruiting
from app.recruiting.kinds import open_url
from app.recruiting.links import LinkOptions
from app.settings import Settings
from app.surveys import crowd, respond
from app.surveys import results as surveys_results
from app.surveys import service as surveys
from app.surveys.sources import source_menus
from app.webhooks.outbox import Owner
from app.webhooks.section import webhooks_context

router = APIRouter(route_class=PageRoute, include_in_schema=False)
RESPOND = "/survey"


def thumb_template(survey_id: int) -> str:
    """Thumbnail URLs of a survey's trees, with ``{study}`` and ``{id}`` for the scripts."""
    return f"/api/surveys/{survey_id}/studies/{{study}}/candidates/{{id}}/thumb"


@router.get("/surveys", dependencies=[ResearcherPage])
def surveys_page(request: Request, session: SessionDep) -> HTMLResponse:
    """Every survey, with a link to create one."""
    rows = [
        (s, respond.list_respondents(session, survey_id=s.id))
        for s in surveys.list_surveys(session)
    ]
    return render(request, "surveys.html", {"rows": rows})


@router.get("/surveys/new", dependencies=[ResearcherPage])
def new_survey_page(request: Request, session: SessionDep) -> HTMLResponse:
    """The new-survey form: trees from menus or files, the paper's or blank questions."""
    return render(
        request, "survey_new.html", {"menus": source_menus(session), "terms": surveys.DEFAULT_TERMS}
    )


def crowd_context(request: Request, session: Session, survey_id: int) -> dict[str, Any]:
    """What the survey page's "Crowd: open link" section shows (the form posts to
    :mod:`app.surveys.crowd_pages`)."""
    kind = crowd.LINK
    row = recruiting.settings(session, kind, survey_id)
    return {
        "crowd": row,
        "crowd_defaults": LinkOptions(),
        "open_url": None if row is None else open_url(kind, request.base_url, row.slug),
        "completed": crowd.completed(session, survey_id=survey_id),
    }


def _survey_context(session: Session, survey: Survey, request: Request) -> dict[str, Any]:
    people = respond.list_respondents(session, survey_id=survey.id)
    base = str(request.base_url).rstrip("/")
    stimuli = surveys.stimuli_of(session, survey_id=survey.id)
    return {
        "survey": survey,
        "stimuli": stimuli,
        "labels": {s.id: s.label for s in stimuli},
        "respondents": [(p, base + respond.invite_path(p.token)) for p in people],
        "results": surveys_results.results(session, survey_id=survey.id),
        "exclusion": surveys.exclusion_text(survey),
        "thumb_template": thumb_template(survey.id),
        **crowd_context(request, session, survey.id),
    }


@router.get("/surveys/{survey_id}", dependencies=[ResearcherPage])
def survey_page(
    survey_id: DbId, request: Request, session: SessionDep, settings: SettingsDep
) -> HTMLResponse:
    """A survey: its stimuli drawn as respondents see them, invite links, results, and
    webhooks."""
    return render_survey_page(request, session, settings, survey_id)


def render_survey_page(
    request: Request,
    session: Session,
    settings: Settings,
    survey_id: int,
    extra: dict[str, Any] | None = None,
    status_code: int = 200,
) -> HTMLResponse:
    """The survey's page, with ``extra`` in its context (a form shown again, say)."""
    survey = surveys.get_survey(session, survey_id=survey_id)
    context = _survey_context(session, survey, request)
    hooks = webhooks_context(session, Owner("survey", survey_id), settings)
    return render(request, "survey.html", context | hooks | (extra or {}), status_code=status_code)


@router.get("/r/{token}")
def survey_invite(token: str, request: Request, session: SessionDep) -> RedirectResponse:
    """Remember the survey invitation in this browser and continue where they left off."""
    return enter_by_invite(
        request, session, members.SURVEY, token, link_name="survey", next_path=lambda _: RESPOND
    )


def _respondent(session: Session, cookie: str | None) -> SurveyRespondent:
    return page_member(
        session,
        members.SURVEY,
        cookie,
        lost="This browser has no valid survey invitation. Open the link you were sent again "
        "(an invite link, /r/..., or the survey's link on your study platform) to start or "
        "continue.",
    )


@router.get(RESPOND)
def respond_page(
    request: Request, session: SessionDep, cookie: RespondentCookie = None
) -> HTMLResponse:
    """The survey, one stimulus per screen (``static/js/survey_respond.js``)."""
    person = _respondent(session, cookie)
    survey = surveys.get_survey(session, survey_id=person.survey_id)
    done, total = respond.progress(session, respondent_id=person.id)
    return render(
        request,
        "survey_respond.html",
        {
            "survey": survey,
            "done": done,
            "total": total,
            "finished": person.finished_at is not None,
            "thumb_template": thumb_template(survey.id),
        },
    )
