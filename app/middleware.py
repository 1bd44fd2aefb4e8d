"""ASGI middleware for every response: a request-body size limit and security headers.

Both are plain ASGI wrappers (no per-request task or body copy on the hot paths). Pages,
``/docs`` and the run report carry their own policy (:data:`app.http.rendering.CSP`,
:mod:`app.http.docs`); everything else (the JSON API, images, static files) gets
``X-Content-Type-Options: nosniff``, no framing, and a policy that allows nothing at all.
"""

from __future__ import annotations

import json

from starlette.datastructures import Headers, MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

#: Largest request body accepted: far above any legitimate one (a study's instructions are
#: at most 20,000 characters), far below what would strain memory.
MAX_BODY_BYTES = 1 << 20
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
    a declared length is enforced by the HTTP parser, so those bodies stream through.
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
            return await self._too_large(send)
        if declared is None and "transfer-encoding" in headers:
            messages = await self._read_chunked(receive)
            if messages is None:
                return await self._too_large(send)
            receive = _replay(messages, receive)
        await self.app(scope, receive, send)

    async def _read_chunked(self, receive: Receive) -> list[Message] | None:
        """The body's messages, or ``None`` as soon as it passes the limit."""
        messages, size = [], 0
        while True:
            message = await receive()
            messages.append(message)
            size += len(message.get("body", b""))
            if size > self.max_bytes:
                return None
            if message["type"] != "http.request" or not message.get("more_body"):
                return messages

    async def _too_large(self, send: Send) -> None:
        body = json.dumps(
            {"detail": f"the request body is larger than {self.max_bytes} bytes"}
        ).encode()
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
