"""The cookies that pages set: the researcher's login and a member's invite token.

Set here, by routes, never by services (a service returns the token; the route that answers
decides what the browser keeps).
"""

from __future__ import annotations

from typing import Any

from fastapi import Response

from app.core.auth import PARTICIPANT_COOKIE, RESEARCHER_COOKIE, researcher_cookie_value
from app.recruiting import members

#: How long a browser remembers a member's invite token, so that they can resume.
MEMBER_COOKIE_MAX_AGE_S = 90 * 24 * 3600


def set_researcher_cookie(
    response: Response, *, admin_token: str, max_age_s: int, secure: bool
) -> None:
    """Log the browser in as the researcher for ``max_age_s`` (HttpOnly, SameSite=Lax; the
    server enforces the age too, see :func:`valid_researcher_cookie`)."""
    response.set_cookie(
        RESEARCHER_COOKIE,
        researcher_cookie_value(admin_token=admin_token),
        max_age=max_age_s,
        httponly=True,
        samesite="lax",
        secure=secure,
    )


def set_member_cookie(
    response: Response, kind: members.CollectionKind[Any], *, token: str, secure: bool
) -> None:
    """Remember a participant or respondent in this browser, so they can resume (HttpOnly,
    SameSite=Lax)."""
    response.set_cookie(
        kind.cookie,
        token,
        max_age=MEMBER_COOKIE_MAX_AGE_S,
        httponly=True,
        samesite="lax",
        secure=secure,
    )


def clear_cookies(response: Response) -> None:
    """Log out both roles."""
    response.delete_cookie(RESEARCHER_COOKIE)
    response.delete_cookie(PARTICIPANT_COOKIE)
