"""``/docs``: Swagger UI from this origin under a strict Content-Security-Policy.

FastAPI's default page loads Swagger UI from a CDN and starts it with an inline script, so it
could only be served without a script policy, on the app's origin (where the researcher's
cookie lives). Here the bundle and its CSS are vendored in ``static/vendor`` (swagger-ui-dist,
with its licence), and the one inline script is allowed by its SHA-256 hash alone. ReDoc is
not served: it would need another bundle and more policy exceptions for the same schema.
"""

from __future__ import annotations

import base64
import hashlib
import re

from fastapi import APIRouter
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse

SWAGGER_JS = "/static/vendor/swagger-ui-bundle.js"
SWAGGER_CSS = "/static/vendor/swagger-ui.css"
# ACV's corrections to Swagger UI's colours (WCAG 2.1 AA contrast); loaded after its CSS.
OVERRIDES_CSS = "/static/css/swagger-overrides.css"
FAVICON = "/static/favicon.svg"
_INLINE_SCRIPT = re.compile(rb"<script>(.*?)</script>", re.DOTALL)


def docs_policy(html: bytes) -> str:
    """The page's policy: this origin only, plus the hash of its one inline script.

    Raises:
        ValueError: the page does not have exactly one inline script (FastAPI changed it).
    """
    scripts = _INLINE_SCRIPT.findall(html)
    if len(scripts) != 1:
        raise ValueError(f"expected one inline script in the docs page, found {len(scripts)}")
    digest = base64.b64encode(hashlib.sha256(scripts[0]).digest()).decode()
    return "; ".join(
        (
            "default-src 'none'",
            f"script-src 'self' 'sha256-{digest}'",
            "style-src 'self'",
            "img-src 'self' data:",
            "connect-src 'self'",
            "base-uri 'none'",
            "form-action 'none'",
            "frame-ancestors 'none'",
        )
    )


def accessible(html: bytes) -> bytes:
    """FastAPI's page with a language (axe's ``html-has-lang``) and ACV's colour overrides.

    Raises:
        ValueError: the page no longer has the ``<html>`` or ``</head>`` it is edited at.
    """
    if html.count(b"<html>") != 1 or html.count(b"</head>") != 1:
        raise ValueError("FastAPI's docs page changed: check docs_router's edits")
    link = f'<link type="text/css" rel="stylesheet" href="{OVERRIDES_CSS}">'.encode()
    return html.replace(b"<html>", b'<html lang="en">').replace(b"</head>", link + b"</head>")


def docs_router(*, openapi_url: str, title: str) -> APIRouter:
    """A router serving Swagger UI for ``openapi_url`` at ``/docs`` (the page is built once)."""
    page = get_swagger_ui_html(
        openapi_url=openapi_url,
        title=title,
        swagger_js_url=SWAGGER_JS,
        swagger_css_url=SWAGGER_CSS,
        swagger_favicon_url=FAVICON,
        swagger_ui_parameters={"validatorUrl": None},
    )  # no badge from swagger.io
    html = accessible(bytes(page.body))  # Starlette types a body as bytes or memoryview
    headers = {"Content-Security-Policy": docs_policy(html), "Referrer-Policy": "no-referrer"}
    router = APIRouter(include_in_schema=False)

    @router.get("/docs")
    async def swagger_ui() -> HTMLResponse:
        return HTMLResponse(html, headers=headers)

    return router
