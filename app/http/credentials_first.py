"""Credentials before the body: an operation that needs credentials checks them before its
body is read, parsed or validated (issue 24, F1).

FastAPI parses and validates a body before the handler runs, and the labelling hot path
checks its invite token inside the handler; so a request without credentials had its body
parsed and judged (a deep one even answered 500). This middleware answers such a request
with the same 401/403/429 the operation's own dependency would give, before the body is
touched. Which credentials an operation takes is read from its OpenAPI ``security``
entries (one home: what the schema declares is what is enforced first); each scheme maps to
a gate that runs the same check as the operation's dependency.
"""

from __future__ import annotations

import inspect
from collections.abc import Awaitable, Callable

from fastapi import FastAPI, Request
from fastapi.routing import RouteContext, iter_route_contexts
from starlette.responses import Response
from starlette.routing import Match
from starlette.types import ASGIApp, Receive, Scope, Send

from app.http.deps import researcher_gate
from app.http.member_auth import evaluator_gate, participant_gate, respondent_gate

Gate = Callable[[Request], Awaitable[None]]
#: The check of each security scheme of the OpenAPI document.
GATES: dict[str, Gate] = {
    "AdminToken": researcher_gate,
    "InviteToken": participant_gate,
    "SurveyInviteToken": respondent_gate,
    "EvaluatorInviteToken": evaluator_gate,
}
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


class CredentialsFirst:
    """Run the gates of an operation with a body before the app reads the body."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app
        self._table: list[tuple[RouteContext, tuple[Gate, ...]]] | None = None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] not in _SAFE_METHODS:
            gates = self._gates(scope)
            if gates:
                request = Request(scope)  # no receive: the body stays unread
                try:
                    await _any_passes(gates, request)
                except Exception as exc:
                    response = await _handled(request, exc)
                    await response(scope, receive, send)
                    return
        await self.app(scope, receive, send)

    def _gates(self, scope: Scope) -> tuple[Gate, ...]:
        if self._table is None:  # built once, from the first write's app
            self._table = gate_table(scope["app"])
        for route, gates in self._table:
            if route.matches(scope)[0] == Match.FULL:
                return gates
        return ()


def gate_table(app: FastAPI) -> list[tuple[RouteContext, tuple[Gate, ...]]]:
    """Each operation that takes a body and declares ``security``, with its gates."""
    paths = app.openapi()["paths"]
    table = []
    for route in iter_route_contexts(app.routes):
        if getattr(route, "body_field", None) is None:
            continue
        for method in route.methods or ():
            operation = paths.get(route.path_format, {}).get(method.lower(), {})
            schemes = [name for entry in operation.get("security", []) for name in entry]
            if schemes:
                table.append((route, tuple(GATES[s] for s in schemes)))
    return table


async def _any_passes(gates: tuple[Gate, ...], request: Request) -> None:
    """Return if one gate passes; else raise the first one's error."""
    first: Exception | None = None
    for gate in gates:
        try:
            return await gate(request)
        except Exception as exc:  # the next scheme may still accept the request
            first = first or exc
    assert first is not None
    raise first


async def _handled(request: Request, exc: Exception) -> Response:
    """The app's own answer to ``exc`` (its exception handlers: one home for error bodies);
    this middleware runs outside the layer that calls them."""
    handlers = request.app.exception_handlers
    handler = next((handlers[c] for c in type(exc).__mro__ if c in handlers), None)
    if handler is None:
        raise exc
    response = handler(request, exc)
    return await response if inspect.isawaitable(response) else response
