"""ASGI middleware for every response: a request-body size limit and security headers.

Both are plain ASGI wrappers (no per-request task or body copy on the hot paths). Pages,
``/docs`` and the run report carry their own policy (:data:`app.http.rendering.CSP`,
:mod:`app.http.docs`); everything else (the JSON API, images, static files) gets
``X-Content-Type-Options: nosniff``, no framing, and a policy that allows nothing at all.
"""

from __future__ import annotations

import json

from fastapi.routing import iter_route_contexts
from starlette.datastructures import Headers, MutableHeaders
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: Largest request body accepted: far above any legitimate one (a study's instructions are
#: at most 20,000 characters), far below what would strain memory.
MAX_BODY_BYTES = 1 << 20
#: The OpenAPI extension by which an operation takes bodies larger than :data:`MAX_BODY_BYTES`.
BODY_LIMIT_KEY = "x-max-body-bytes"
#: Added where a response does not set its own value.
DEFAULT_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "no-referrer",
}
#: For responses without a policy of their own (HTML included: a page that needs more must
#: say so itself).
DEFAULT_CSP = "default-src 'none'; frame-ancestors 'none'"


class BodySizeLimit:
    """Answer 413 to bodies over ``max_bytes``, declared (``Content-Length``) or streamed.

    A chunked body (no ``Content-Length``) is read up to the limit before the app sees it;
    a declared length is enforced by the HTTP parser, so those bodies stream through. An
    operation that takes larger bodies (an uploaded policy) says so with the OpenAPI extension
    :data:`BODY_LIMIT_KEY`; its limit is looked up only for a body over ``max_bytes``, so
    every other request pays nothing for it.
    """

    def __init__(self, app: ASGIApp, max_bytes: int = MAX_BODY_BYTES) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = Headers(scope=scope)
        declared = headers.get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            limit = route_body_limit(scope, self.max_bytes)
            if int(declared) > limit:
                return await self._too_large(send, limit)
        if declared is None and "transfer-encoding" in headers:
            messages, limit = await self._read_chunked(scope, receive)
            if messages is None:
                return await self._too_large(send, limit)
            receive = _replay(messages, receive)
        await self.app(scope, receive, send)

    async def _read_chunked(
        self, scope: Scope, receive: Receive
    ) -> tuple[list[Message] | None, int]:
        """The body's messages, or ``None`` as soon as it passes the limit; and the limit."""
        messages, size, limit = [], 0, self.max_bytes
        while True:
            message = await receive()
            messages.append(message)
            size += len(message.get("body", b""))
            if size > limit == self.max_bytes:
                limit = route_body_limit(scope, self.max_bytes)
            if size > limit:
                return None, limit
            if message["type"] != "http.request" or not message.get("more_body"):
                return messages, limit

    async def _too_large(self, send: Send, limit: int) -> None:
        body = json.dumps({"detail": f"the request body is larger than {limit} bytes"}).encode()
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", b"%d" % len(body)),
                    (b"connection", b"close"),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})


def route_body_limit(scope: Scope, default: int) -> int:
    """The largest body the operation that ``scope`` asks for takes: its OpenAPI
    :data:`BODY_LIMIT_KEY`, else ``default``."""
    app = scope.get("app")
    for route in iter_route_contexts(getattr(app, "routes", ())):
        extra = getattr(route, "openapi_extra", None)
        if extra and BODY_LIMIT_KEY in extra and route.matches(scope)[0] == Match.FULL:
            return max(default, int(extra[BODY_LIMIT_KEY]))
    return default


def _replay(messages: list[Message], receive: Receive) -> Receive:
    """A ``receive`` that hands out ``messages`` first, then defers to the real one."""
    pending = list(messages)

    async def replay() -> Message:
        return pending.pop(0) if pending else await receive()

    return replay


class SecurityHeaders:
    """Add :data:`DEFAULT_HEADERS` and a Content-Security-Policy where a response lacks them."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            return await self.app(scope, receive, send)

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                for name, value in DEFAULT_HEADERS.items():
                    headers.setdefault(name, value)
                headers.setdefault("Content-Security-Policy", DEFAULT_CSP)
            await send(message)

        await self.app(scope, receive, send_with_headers)
