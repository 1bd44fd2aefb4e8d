"""CSRF protection for the pages' form posts: a signed double-submit token.

Each browser gets a random value in an HttpOnly ``SameSite=Strict`` cookie; every form
carries ``HMAC(key, cookie value)`` in a hidden field, and a post is accepted only when the
two match (:func:`secrets.compare_digest`). The key is derived from the admin token, so a
value planted in the cookie (e.g. from a sibling subdomain) cannot be paired with a valid
field without the server's secret. JSON calls from the pages send ``X-Requested-With: acv``
instead (see ``static/js/api.js``), which a cross-site form cannot set.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from typing import Annotated

from fastapi import Depends, Request, Response

from app.core.errors import ForbiddenError
from app.http.deps import AJAX_HEADER as AJAX_HEADER  # re-exported for the pages
from app.http.deps import RuntimeDep

CSRF_COOKIE = "acv_csrf"
CSRF_FIELD = "csrf_token"
_MAX_CHARS = 256


def _key(admin_token: str) -> bytes:
    return hmac.new(admin_token.encode(), b"acv-csrf-key", hashlib.sha256).digest()


def browser_value(request: Request) -> str:
    """This browser's CSRF cookie value, or a fresh one (set it with :func:`remember`)."""
    value = request.cookies.get(CSRF_COOKIE, "")
    return value if 16 <= len(value) <= _MAX_CHARS else secrets.token_urlsafe(32)


def form_token(admin_token: str, value: str) -> str:
    """The hidden-field token that pairs with cookie ``value``."""
    return hmac.new(_key(admin_token), value.encode(), hashlib.sha256).hexdigest()


def remember(request: Request, response: Response, value: str) -> None:
    """Set the CSRF cookie on ``response`` unless the browser already holds ``value``."""
    if request.cookies.get(CSRF_COOKIE) != value:
        response.set_cookie(
            CSRF_COOKIE,
            value,
            httponly=True,
            samesite="strict",
            secure=request.url.scheme == "https",
        )


async def form_fields(request: Request) -> dict[str, str]:
    """The posted form's text fields (files are ignored)."""
    form = await request.form()
    return {k: v for k, v in form.items() if isinstance(v, str)}


FormFields = Annotated[dict[str, str], Depends(form_fields)]


def verify_csrf(request: Request, runtime: RuntimeDep, fields: FormFields) -> None:
    """Reject a form post whose token does not pair with the browser's CSRF cookie.

    Raises:
        ForbiddenError: missing or mismatched token (shown as an error page).
    """
    value = request.cookies.get(CSRF_COOKIE, "")
    given = fields.get(CSRF_FIELD, "")
    if (
        not value
        or len(value) > _MAX_CHARS
        or len(given) > _MAX_CHARS
        or not secrets.compare_digest(
            given.encode(), form_token(runtime.admin_token, value).encode()
        )
    ):
        raise ForbiddenError(
            "This form has expired or did not come from this site. "
            "Go back, reload the page and try again."
        )


CsrfChecked = Depends(verify_csrf)
