"""A study's open link ``/s/<slug>`` (issue 14): consent, a participant per new visitor
(rate-limited, :func:`app.recruiting.pages.admit`), "this study is full", and the consistency
check after the bracket."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session

from app.core import auth
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep
from app.http.guards import PageParticipant
from app.http.rendering import PageRoute, RedirectTo, is_https, redirect, render
from app.labelling import check as crowd_check
from app.labelling import participants
from app.labelling.pages import THANKS, where_next
from app.models import CrowdSettings
from app.recruiting import pages as open_links
from app.recruiting import service as recruiting
from app.recruiting.links import check_open, is_full
from app.studies import crowd
from app.studies import service as studies

router = APIRouter(route_class=PageRoute, include_in_schema=False)
CHECK = "/participate/check"


def _name(session: Session, link: CrowdSettings) -> str:
    return studies.get_ready_study(session, study_id=link.study_id).name


def _enter(
    request: Request, session: Session, link: CrowdSettings, ids: dict[str, str]
) -> Response:
    """Resume a returning visitor, or make a participant of a new one (rate-limited)."""
    token = request.cookies.get(auth.PARTICIPANT_COOKIE)
    person = recruiting.returning(session, crowd.LINK, link=link, ids=ids, token=token)
    if person is None:
        person = open_links.admit(
            request, lambda: recruiting.join(session, crowd.LINK, link=link, ids=ids)
        )
    response = redirect(where_next(participants.progress(session, participant=person)))
    auth.set_member_cookie(
        response, crowd.LINK.members, token=person.token, secure=is_https(request)
    )
    return response


@router.get("/s/{slug}")
def open_link(slug: str, request: Request, session: SessionDep) -> Response:
    """The consent page, or straight on to the instructions; "full" past the maximum."""
    link = recruiting.open_link(session, crowd.LINK, slug)
    ids = recruiting.external_ids(link, open_links.query(request))
    returning = recruiting.returning(
        session, crowd.LINK, link=link, ids=ids, token=request.cookies.get(auth.PARTICIPANT_COOKIE)
    )
    if returning is None:
        check_open(link, what="study")
    if returning is None and is_full(link):
        return _full(request, session, link)
    if returning is None and link.consent_text:
        return open_links.consent(
            request, _name(session, link), link, crowd.LINK.open_path(link.slug), ids
        )
    return _join_or_full(request, session, link, ids)


def _full(request: Request, session: Session, link: CrowdSettings) -> Response:
    return open_links.full(request, _name(session, link), crowd.LINK)


def _join_or_full(
    request: Request, session: Session, link: CrowdSettings, ids: dict[str, str]
) -> Response:
    try:
        return _enter(request, session, link, ids)
    except crowd.StudyFullError:
        return _full(request, session, link)


@router.post("/s/{slug}", dependencies=[CsrfChecked])
def consent(slug: str, request: Request, session: SessionDep, fields: FormFields) -> Response:
    """Agree (a participant is made) or decline (only the count of declines grows)."""
    link = recruiting.open_link(session, crowd.LINK, slug)
    ids = recruiting.external_ids(link, fields)
    if fields.get("decision") != "agree":
        recruiting.decline(session, crowd.LINK, link=link)
        return open_links.message(
            request, _name(session, link), "You declined", open_links.DECLINED
        )
    return _join_or_full(request, session, link, ids)


@router.get(CHECK)
def check_page(request: Request, session: SessionDep, person: PageParticipant) -> Response:
    """One first-round pair again, sides swapped (only when the study asks for it)."""
    pair = crowd_check.pending_pair(session, participant=person)
    if pair is None:
        raise RedirectTo(THANKS)
    return render(
        request,
        "crowd_check.html",
        {"study": studies.get_ready_study(session, study_id=person.study_id), "pair": pair},
    )


@router.post(CHECK, dependencies=[CsrfChecked])
def check_answer(session: SessionDep, person: PageParticipant, fields: FormFields) -> Response:
    """Store the check's answer (a plain form: two buttons), then the thank-you page."""
    try:
        winner = int(fields.get("winner", ""))
    except ValueError:
        winner = -1
    crowd_check.answer(session, participant=person, winner=winner)
    return redirect(THANKS)
