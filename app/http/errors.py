"""Exception handlers: every error is JSON ``{"detail": ...}`` with a 4xx status where the
request was at fault, 503 when the database is unreachable, never a stack trace; a browser
asking for a page gets an HTML page saying the same (pages' own errors: ``PageRoute``)."""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar, cast

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from fastapi.routing import iter_route_contexts
from pydantic import BaseModel
from sqlalchemy.exc import DataError, OperationalError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match
from starlette.types import ExceptionHandler

from app.core.errors import AuthError, PendingError, ServiceError, TooManyAttemptsError
from app.http import bounded
from app.http.rendering import error_page
from engine.errors import InputError

log = logging.getLogger(__name__)

E = TypeVar("E", bound=Exception)


class ErrorOut(BaseModel):
    """Every error answer: a message, or the list of validation errors (422)."""

    detail: str | list[dict[str, Any]]


#: Error answers any API operation may give, documented in the OpenAPI schema as JSON
#: (explicitly: a ``model`` would be documented in the route's own media type, e.g. CSV).
RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {
        "description": text,
        "content": {"application/json": {"schema": ErrorOut.model_json_schema()}},
    }
    for code, text in (
        (400, "The body could not be parsed (malformed JSON, or not UTF-8)."),
        (401, "No valid credentials for this operation."),
        (
            403,
            "Credentials that do not allow this, or a write authenticated by a cookie "
            "without the X-Requested-With header.",
        ),
        (404, "No such object, or not visible to the caller."),
        (409, "The request conflicts with the stored state."),
        (413, "The request body is too large."),
        (422, "Invalid input."),
        (429, "Too many failed researcher credentials from this address; see Retry-After."),
        (503, "The database is unavailable; try again."),
    )
}


def _validation_error(_: Request, exc: RequestValidationError) -> JSONResponse:
    """FastAPI's 422, bounded (:mod:`app.http.bounded`): a deep or wide body gives a short
    answer, never an echo of itself, and inputs JSON cannot hold (NaN, surrogates) are safe."""
    return JSONResponse({"detail": bounded.errors(exc.errors())}, status_code=422)


async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
    """FastAPI's answer, except that a 405 lists every method of the path in ``Allow``
    (Starlette names the first matching route's only, and FastAPI has a route per method),
    and a browser asking for a page that does not exist, or for a form's target, gets a page
    that says so."""
    if exc.status_code == 404 and _wants_a_page(request):
        return error_page(request, 404, "There is no such page. Check the link you were given.")
    if exc.status_code == 405:
        methods = sorted(
            {
                m
                for route in iter_route_contexts(request.app.routes)
                if route.methods and route.matches(request.scope)[0] != Match.NONE
                for m in route.methods
            }
        )
        allow = {"Allow": ", ".join(methods)}
        if _wants_a_page(request):  # a form's target opened as a page (after a login, say)
            page = error_page(request, 405, "This address only takes a form: open its page.")
            page.headers.update(allow)
            return page
        exc = StarletteHTTPException(405, exc.detail, headers=allow)
    return await http_exception_handler(request, exc)


def _wants_a_page(request: Request) -> bool:
    """A browser's request outside the API and the static files (its ``Accept`` names HTML)."""
    path = request.url.path
    outside = not path.startswith(("/api/", "/static/"))
    return outside and "text/html" in request.headers.get("accept", "")


def _input_error(_: Request, exc: InputError) -> JSONResponse:
    return JSONResponse({"detail": bounded.text(str(exc))}, status_code=422)


def _service_error(_: Request, exc: ServiceError) -> JSONResponse:
    headers = {"WWW-Authenticate": "Bearer"} if isinstance(exc, AuthError) else None
    if isinstance(exc, TooManyAttemptsError):
        headers = {"Retry-After": str(exc.retry_after_s)}
    if isinstance(exc, PendingError):  # not a failure: the client polls
        return JSONResponse(
            {"status": "pending", "detail": exc.detail},
            status_code=202,
            headers={"Retry-After": "2"},
        )
    return JSONResponse(
        {"detail": bounded.text(exc.detail)}, status_code=exc.status_code, headers=headers
    )


def _unstorable(request: Request, exc: DataError) -> Response:
    log.warning("refused value: %s", bounded.text(str(exc)))
    return _answer(request, 422, "a value in the request cannot be stored")


def _database_down(request: Request, exc: OperationalError) -> Response:
    log.error("database error: %s", bounded.text(str(exc)))
    return _answer(request, 503, "the database is unavailable; try again", {"Retry-After": "1"})


def _unexpected(request: Request, exc: Exception) -> Response:
    log.exception("unhandled error", exc_info=exc)
    return _answer(request, 500, "internal server error")


#: A failure's words on an HTML page, by status (the API's ``detail`` is terser).
_PAGE_WORDS = {
    422: "Something you sent cannot be stored. Go back, check what you typed and try again.",
    503: "The service is briefly unavailable. Nothing was lost: go back and try again in a moment.",
    500: "Something went wrong on our side. Go back and try again; if it happens again, tell "
    "the researchers.",
}


def _answer(
    request: Request, status: int, detail: str, headers: dict[str, str] | None = None
) -> Response:
    """``{"detail": ...}``, or for a browser's page an HTML page saying the same in words."""
    if _wants_a_page(request):
        page = error_page(request, status, _PAGE_WORDS[status])
        page.headers.update(headers or {})
        return page
    return JSONResponse({"detail": detail}, status_code=status, headers=headers)


def install(app: FastAPI) -> None:
    """Register the handlers on ``app``."""
    _handle(app, RequestValidationError, _validation_error)
    _handle(app, StarletteHTTPException, _http_error)
    _handle(app, InputError, _input_error)
    _handle(app, ServiceError, _service_error)
    _handle(app, DataError, _unstorable)
    _handle(app, OperationalError, _database_down)
    _handle(app, Exception, _unexpected)


def _handle(
    app: FastAPI,
    exc_class: type[E],
    handler: Callable[[Request, E], Response | Awaitable[Response]],
) -> None:
    """``app.add_exception_handler``, with the handler typed for the class it handles.

    Starlette types every handler as taking any ``Exception``; it only ever passes one of
    ``exc_class``, so the cast is safe and the signature above still checks each handler.
    """
    app.add_exception_handler(exc_class, cast(ExceptionHandler, handler))
