"""Researcher login and logout, and the site root.

The login page takes the admin token in a password field (posted with a CSRF token) and
sets the researcher cookie, a signed login time (never the token itself) that the server
accepts for ``ACV_SESSION_HOURS``. A link ``/login#token=...`` fills the field from the URL
fragment, which browsers never send to the server, so the token stays out of access logs.
"""

from __future__ import annotations

import logging
from typing import Annotated

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import HTMLResponse, RedirectResponse

from app.core import auth
from app.core.errors import AuthError
from app.http import cookies
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import ResearcherCookie, RuntimeDep, SessionDep
from app.http.guards import ParticipantCookie, safe_next
from app.http.ratelimit import client_address, login_limiter
from app.http.rendering import PageRoute, is_https, redirect, render
from app.recruiting import members

log = logging.getLogger(__name__)
router = APIRouter(route_class=PageRoute, include_in_schema=False)


@router.get("/")
def home(
    runtime: RuntimeDep,
    session: SessionDep,
    researcher: ResearcherCookie = None,
    participant: ParticipantCookie = None,
) -> RedirectResponse:
    """The researcher's studies, a participant's bracket, or the login page."""
    if auth.is_researcher(
        admin_token=runtime.admin_token,
        cookie=researcher,
        max_age_s=runtime.settings.session_max_age_s,
    ):
        return redirect("/studies")
    if participant:
        try:
            members.member_by_token(session, members.STUDY, token=participant)
            return redirect("/participate")
        except AuthError:
            pass
    return redirect("/login")


@router.get("/login")
def login_page(
    request: Request, next_path: Annotated[str | None, Query(alias="next")] = None
) -> HTMLResponse:
    """The researcher login form; ``next`` is where to go after logging in."""
    return render(request, "login.html", {"next": safe_next(next_path)})


@router.post("/login", dependencies=[CsrfChecked])
def login(request: Request, runtime: RuntimeDep, fields: FormFields) -> Response:
    """Check the pasted admin token; on success set the researcher cookie and go on."""
    target = safe_next(fields.get("next"))
    token = fields.get("token", "").strip()
    limiter, address = login_limiter(request), client_address(request)
    if limiter.blocked(address):  # refused before the token is even compared
        wait_s = limiter.retry_after_s(address)
        response = render(
            request,
            "login.html",
            {
                "next": target,
                "error": (f"Too many failed logins from this address. Try again in {wait_s} s."),
            },
            status_code=429,
        )
        response.headers["Retry-After"] = str(wait_s)
        return response
    if not auth.is_researcher(admin_token=runtime.admin_token, bearer=token):
        limiter.failed(address)
        log.warning("failed researcher login from %s", address)
        return render(
            request,
            "login.html",
            {
                "next": target,
                "error": (
                    "That is not the admin token. It is printed when the server starts, and kept "
                    "in the data directory's admin_token file."
                ),
            },
            status_code=401,
        )
    logged_in = redirect(target)
    cookies.set_researcher_cookie(
        logged_in,
        admin_token=runtime.admin_token,
        max_age_s=runtime.settings.session_max_age_s,
        secure=is_https(request),
    )
    return logged_in


@router.post("/logout", dependencies=[CsrfChecked])
def logout() -> RedirectResponse:
    """Forget both roles in this browser."""
    response = redirect("/login")
    cookies.clear_cookies(response)
    return response
