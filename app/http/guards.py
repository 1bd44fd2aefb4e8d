"""Who may see a page: the researcher (cookie set by the login page) or a participant
(cookie set by their invite link ``/p/<token>``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated

from fastapi import Cookie, Depends, Request
from fastapi.responses import RedirectResponse
from sqlalchemy.orm import Session
from starlette.routing import Match

from app.core import auth
from app.core.errors import AuthError, NotFoundError
from app.http import cookies
from app.http.deps import ResearcherCookie, RuntimeDep, SessionDep
from app.http.rendering import RedirectTo, is_https, login_url, redirect
from app.models import Participant
from app.recruiting import members
from app.recruiting.members import CollectionKind, MemberRow

DEFAULT_NEXT = "/studies"
ParticipantCookie = Annotated[str | None, Cookie(alias=auth.PARTICIPANT_COOKIE)]


def researcher_page(request: Request, runtime: RuntimeDep, cookie: ResearcherCookie = None) -> None:
    """Let the researcher through; send anyone else to the login page (and back after)."""
    if not auth.is_researcher(
        admin_token=runtime.admin_token, cookie=cookie, max_age_s=runtime.settings.session_max_age_s
    ):
        raise RedirectTo(login_url(_back_to(request)))


def _back_to(request: Request) -> str:
    """The page to return to after logging in: this one, or for a form posted when the login
    had lapsed, the nearest page above its target (which may take no ``GET``)."""
    path = request.url.path
    if request.method in ("GET", "HEAD"):
        return path
    while path := path.rsplit("/", 1)[0]:
        scope = {"type": "http", "path": path, "method": "GET"}
        if any(route.matches(scope)[0] == Match.FULL for route in request.app.routes):
            return path
    return DEFAULT_NEXT


ResearcherPage = Depends(researcher_page)


def page_member(
    session: Session, kind: CollectionKind[MemberRow], cookie: str | None, *, lost: str
) -> MemberRow:
    """The member of ``kind`` whose invite cookie this browser holds.

    Raises:
        AuthError: ``lost`` (what to do, for the error page), when there is no cookie or its
            token is no longer valid.
    """
    try:
        return members.member_by_token(session, kind, token=cookie)
    except AuthError:
        raise AuthError(lost) from None


def enter_by_invite(
    request: Request,
    session: Session,
    kind: CollectionKind[MemberRow],
    token: str,
    *,
    link_name: str,
    next_path: Callable[[MemberRow], str],
) -> RedirectResponse:
    """A member's invite link (``/p/``, ``/r/``, ``/v/``): remember the invitation in this
    browser (the kind's cookie) and go on to ``next_path(member)``.

    Raises:
        NotFoundError: "This ``link_name`` link is not valid ..." for a token nobody holds.
    """
    try:
        person = members.member_by_token(session, kind, token=token)
    except AuthError:
        raise NotFoundError(
            f"This {link_name} link is not valid. Check that you copied all of it, "
            "or ask the researcher for a new one."
        ) from None
    response = redirect(next_path(person))
    cookies.set_member_cookie(response, kind, token=token, secure=is_https(request))
    return response


def page_participant(session: SessionDep, cookie: ParticipantCookie = None) -> Participant:
    """The participant whose invite cookie this browser holds (:func:`page_member`)."""
    return page_member(
        session,
        members.STUDY,
        cookie,
        lost="This browser has no valid invitation. Open the link you were sent again (an "
        "invite link, /p/..., or the study's link on your study platform) to start or continue.",
    )


PageParticipant = Annotated[Participant, Depends(page_participant)]


def safe_next(target: str | None) -> str:
    """``target`` if it is a path on this site, else the study list (no open redirects)."""
    if (
        not target
        or not target.startswith("/")
        or target.startswith("//")
        or "\\" in target
        or not target.isprintable()
        or len(target) > 500
    ):
        return DEFAULT_NEXT
    return target
