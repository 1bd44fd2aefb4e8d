"""Rendering pages: Jinja2 templates, security headers, redirects and HTML error pages.

Every page is sent with a Content-Security-Policy that allows scripts and styles from this
origin only (no inline code: pages pass data to ``static/js`` through ``data-*``
attributes), ``Referrer-Policy: no-referrer`` (URLs may hold invite tokens) and
``Cache-Control: no-store``.
"""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from datetime import datetime
from http import HTTPStatus
from typing import Any
from urllib.parse import quote

from fastapi import Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, RedirectResponse
from fastapi.routing import APIRoute
from fastapi.templating import Jinja2Templates

from app.core.errors import ServiceError
from app.core.resources import TEMPLATES_DIR
from app.http import csrf
from app.http.urls import image_url
from app.models import as_utc
from engine.errors import InputError

CSP = "; ".join(
    (
        "default-src 'self'",
        "script-src 'self'",
        "style-src 'self'",
        "img-src 'self' data:",
        "connect-src 'self'",
        "object-src 'none'",
        "base-uri 'none'",
        "form-action 'self'",
        "frame-ancestors 'none'",
    )
)
SECURITY_HEADERS = {
    "Content-Security-Policy": CSP,
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Cache-Control": "no-store",
}


def _when(moment: datetime | None) -> str:
    """A stored time for people: ``2025-01-31 14:05 UTC``."""
    return as_utc(moment).strftime("%Y-%m-%d %H:%M UTC") if moment else ""


templates = Jinja2Templates(directory=TEMPLATES_DIR)
templates.env.filters["when"] = _when
#: How long an open link's last page waits before it sends the person back to the platform:
#: long enough to read and copy the code, with a button to stay (static/js/complete.js).
templates.env.globals["redirect_ms"] = 20_000


def is_https(request: Request) -> bool:
    """Whether cookies for this request should be ``Secure``."""
    return request.url.scheme == "https"


def render(
    request: Request, name: str, context: dict[str, Any] | None = None, *, status_code: int = 200
) -> HTMLResponse:
    """Render template ``name`` with the CSRF field value and the security headers."""
    admin_token: str = request.app.state.runtime.admin_token
    value = csrf.browser_value(request)
    ctx = {
        "csrf_field": csrf.CSRF_FIELD,
        "csrf_token": csrf.form_token(admin_token, value),
        **(context or {}),
    }
    response = templates.TemplateResponse(
        request, name, ctx, status_code=status_code, headers=SECURITY_HEADERS
    )
    csrf.remember(request, response, value)
    return response


def redirect(url: str) -> RedirectResponse:
    """A 303 redirect (after a form post the browser follows with GET)."""
    return RedirectResponse(url, status_code=303, headers=SECURITY_HEADERS)


def thumb_template(study_id: int) -> str:
    """A study's thumbnail URL with ``{id}`` where the candidate id goes (for scripts)."""
    return image_url(study_id, 0, "thumb").replace("/candidates/0/", "/candidates/{id}/")


def login_url(next_path: str) -> str:
    return "/login?next=" + quote(next_path, safe="/")


class RedirectTo(Exception):  # noqa: N818 (a control-flow signal, not an error)
    """Raised by page dependencies to send the browser elsewhere (e.g. to the login page)."""

    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.url = url


def error_page(
    request: Request, status_code: int, message: str, title: str | None = None
) -> HTMLResponse:
    """An HTML error page (pages never answer with the API's JSON errors), headed ``title``
    or else the status's phrase."""
    try:
        title = title or HTTPStatus(status_code).phrase
    except ValueError:
        title = "Error"
    return render(
        request,
        "error.html",
        {"title": title, "message": message, "status_code": status_code},
        status_code=status_code,
    )


def _page_error(request: Request, exc: Exception) -> HTMLResponse:
    if isinstance(exc, ServiceError):
        return error_page(request, exc.status_code, exc.detail, exc.title)
    if isinstance(exc, InputError):
        return error_page(request, 422, str(exc))
    return error_page(request, 404, "There is no such page.")  # malformed path parameter


class PageRoute(APIRoute):
    """A route whose failures become HTML pages or redirects instead of JSON errors.

    A ``GET`` page also answers ``HEAD`` (link checkers and previewers send it), as
    Starlette's own routes do and FastAPI's do not; the server sends no body for it. It runs
    the ``GET``, which never makes a member (:mod:`app.recruiting.pages`).
    """

    def __init__(self, path: str, endpoint: Callable[..., Any], **kwargs: Any) -> None:
        if set(kwargs.get("methods") or ()) == {"GET"}:
            kwargs["methods"] = {"GET", "HEAD"}
        super().__init__(path, endpoint, **kwargs)

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def page_handler(request: Request) -> Response:
            try:
                return await handler(request)
            except RedirectTo as exc:
                return redirect(exc.url)
            except (ServiceError, InputError, RequestValidationError) as exc:
                return _page_error(request, exc)

        return page_handler
