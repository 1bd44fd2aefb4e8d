"""FastAPI dependencies as ``Annotated`` aliases: runtime, settings, session and callers.

``ResearcherDep`` accepts ``Authorization: Bearer <admin token>`` or the researcher cookie;
``ViewerDep`` accepts that or a participant's invite token (bearer or cookie) and says which;
members' own dependencies are :mod:`app.http.member_auth`. A bearer token that is neither the admin
token nor an invite token counts as a failed login of the client's address
(:mod:`app.http.ratelimit`); past the limit, researcher bearer tokens are refused with 429
before being compared.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated

import anyio.to_thread
from fastapi import Cookie, Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.core import auth
from app.core.errors import AuthError, ForbiddenError, TooManyAttemptsError
from app.core.json_types import IntParam
from app.core.limits import MAX_DB_ID
from app.db import POOL_CAPACITY
from app.models import Participant
from app.recruiting import members
from app.runtime import Runtime
from app.settings import Settings

if TYPE_CHECKING:  # ratelimit is built at startup; only its type is needed here
    from app.http.ratelimit import LoginLimiter

log = logging.getLogger(__name__)

_admin_bearer = HTTPBearer(
    auto_error=False,
    scheme_name="AdminToken",
    description="The researcher's admin token (ACV_ADMIN_TOKEN).",
)
invite_bearer = HTTPBearer(
    auto_error=False, scheme_name="InviteToken", description="A participant's invite token."
)
BearerCredentials = HTTPAuthorizationCredentials | None
#: The bearer token, documented in OpenAPI as the researcher's scheme.
AdminCredentials = Annotated[BearerCredentials, Depends(_admin_bearer)]
#: The same bearer token, documented as a participant's scheme: an operation that takes both
#: depends on both, so its OpenAPI ``security`` lists both (as alternatives).
InviteCredentials = Annotated[BearerCredentials, Depends(invite_bearer)]
#: The researcher's login cookie, unchecked.
ResearcherCookie = Annotated[str | None, Cookie(alias=auth.RESEARCHER_COOKIE)]

#: Requests holding a database session at once: below the pool's capacity
#: (:data:`app.db.POOL_CAPACITY`), leaving connections for background jobs.
MAX_SESSIONS = POOL_CAPACITY - 8
#: Database ids in paths and queries (:class:`~app.core.json_types.IntParam`: decimal digits).
DbId = Annotated[int, IntParam(ge=1, le=MAX_DB_ID)]
#: Candidate ids in paths: ``0 .. N-1`` with ``N <= 128``.
CandidateId = Annotated[int, IntParam(ge=0, le=127)]
#: Largest checkpoint step a query names (steps are 64-bit integers in the database).
MAX_STEP = 2**62
#: A checkpoint step in a query: the run's timesteps when it was saved.
StepParam = Annotated[int, IntParam(ge=0, le=MAX_STEP)]
#: Header the pages' scripts send on every JSON call (``static/js/api.js``). A cross-site
#: form cannot set it, so a cookie-authenticated write without it may be forged (CSRF).
AJAX_HEADER = ("X-Requested-With", "acv")
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def check_cookie_write(request: Request) -> None:
    """Refuse a state-changing call authenticated by a cookie without :data:`AJAX_HEADER`.

    Bearer-token calls are exempt: browsers never attach those on their own.
    """
    name, value = AJAX_HEADER
    if request.method not in _SAFE_METHODS and request.headers.get(name) != value:
        raise ForbiddenError(
            f"a {request.method} authenticated by a cookie must send the header {name}: {value}"
        )


async def get_runtime(request: Request) -> Runtime:  # async: no thread hop for a lookup
    return request.app.state.runtime


RuntimeDep = Annotated[Runtime, Depends(get_runtime)]


async def get_settings(runtime: RuntimeDep) -> Settings:
    return runtime.settings


SettingsDep = Annotated[Settings, Depends(get_settings)]


async def get_session(runtime: RuntimeDep) -> AsyncIterator[Session]:
    """One session per request; services commit their own writes.

    At most :data:`MAX_SESSIONS` requests hold a session at a time; the others wait without
    a worker thread. A request holds its connection while it waits for worker threads (to
    run the handler, then to validate the response), so without this bound a burst of
    requests can take every pooled connection while the threads wait for one: a deadlock.
    """
    session = runtime.sessions()
    try:
        yield session
    finally:
        session.close()


SessionDep = Annotated[
    Session, Depends(get_session, scope="function", max_concurrency=MAX_SESSIONS)
]


@dataclass(frozen=True)
class Viewer:
    """Who is asking: the researcher, a participant, or (for ``ViewerDep``) either."""

    researcher: bool
    participant: Participant | None = None


def bearer_value(credentials: BearerCredentials) -> str | None:
    """The token of an ``Authorization: Bearer`` header, if one was sent."""
    return credentials.credentials if credentials is not None else None


_RESEARCHER_REQUIRED = "researcher credentials required (Authorization: Bearer <admin token>)"


def _limiter(request: Request) -> tuple[LoginLimiter, str]:
    """The app's failed-login limiter and the client's address (as the login form counts)."""
    return request.app.state.login_limiter, request.client.host if request.client else "unknown"


def _too_many(limiter: LoginLimiter, address: str) -> TooManyAttemptsError:
    return TooManyAttemptsError(
        "too many failed researcher credentials from this address; try again later",
        retry_after_s=limiter.retry_after_s(address),
    )


def _failed(limiter: LoginLimiter, address: str) -> None:
    limiter.failed(address)
    log.warning("failed researcher bearer token from %s", address)


def _is_invite_token(runtime: Runtime, token: str) -> bool:
    with runtime.sessions() as session:
        return members.is_member_token(session, token=token)


def _refusal(limiter: LoginLimiter, address: str) -> TooManyAttemptsError | None:
    """The 429 of an address past the failed-login limit, else ``None`` (the counts are in
    the database: called on a worker thread)."""
    return _too_many(limiter, address) if limiter.blocked(address) else None


def _guessed(runtime: Runtime, limiter: LoginLimiter, address: str, token: str) -> None:
    """Count a wrong bearer token as a failed login, unless it is a participant's own invite
    token (a credential of another role, not a guess). On a worker thread."""
    if not _is_invite_token(runtime, token):
        _failed(limiter, address)


async def require_researcher(
    request: Request,
    runtime: RuntimeDep,
    credentials: Annotated[BearerCredentials, Depends(_admin_bearer)],
    cookie: Annotated[str | None, Cookie(alias=auth.RESEARCHER_COOKIE)] = None,
) -> Viewer:
    """The researcher, or 401 (429 after too many failed bearer tokens from this address;
    403 for a cookie write without :data:`AJAX_HEADER`). A bearer token, when sent, decides."""
    if (token := bearer_value(credentials)) is not None:
        limiter, address = _limiter(request)
        # refused before comparing, or guessing would go on
        if (refused := await anyio.to_thread.run_sync(_refusal, limiter, address)) is not None:
            raise refused
        if auth.is_researcher(admin_token=runtime.admin_token, bearer=token):
            return Viewer(researcher=True)
        await anyio.to_thread.run_sync(_guessed, runtime, limiter, address, token)
        raise AuthError(_RESEARCHER_REQUIRED)
    if not auth.is_researcher(
        admin_token=runtime.admin_token, cookie=cookie, max_age_s=runtime.settings.session_max_age_s
    ):
        raise AuthError(_RESEARCHER_REQUIRED)
    check_cookie_write(request)
    return Viewer(researcher=True)


ResearcherDep = Annotated[Viewer, Depends(require_researcher)]


async def researcher_gate(request: Request) -> None:
    """:func:`require_researcher`, on a request whose body is not read yet
    (:mod:`app.http.credentials_first`)."""
    await require_researcher(
        request,
        request.app.state.runtime,
        await _admin_bearer(request),
        request.cookies.get(auth.RESEARCHER_COOKIE),
    )


def get_viewer(
    request: Request,
    runtime: RuntimeDep,
    session: SessionDep,
    credentials: AdminCredentials,
    _as_invite: InviteCredentials,
    researcher_cookie: Annotated[str | None, Cookie(alias=auth.RESEARCHER_COOKIE)] = None,
    participant_cookie: Annotated[str | None, Cookie(alias=auth.PARTICIPANT_COOKIE)] = None,
) -> Viewer:
    """The researcher if their credentials are sent, else the participant, else 401. A
    bearer token, when sent, decides; past the failed-login limit only invite tokens work."""
    if (token := bearer_value(credentials)) is not None:
        limiter, address = _limiter(request)
        blocked = limiter.blocked(address)
        if not blocked and auth.is_researcher(admin_token=runtime.admin_token, bearer=token):
            return Viewer(researcher=True)
        try:
            participant = members.member_by_token(session, members.STUDY, token=token)
        except AuthError:
            if blocked:
                raise _too_many(limiter, address) from None
            _failed(limiter, address)
            raise
    else:
        if researcher_cookie or participant_cookie:
            check_cookie_write(request)
        if auth.is_researcher(
            admin_token=runtime.admin_token,
            cookie=researcher_cookie,
            max_age_s=runtime.settings.session_max_age_s,
        ):
            return Viewer(researcher=True)
        participant = members.member_by_token(session, members.STUDY, token=participant_cookie)
    session.commit()  # as in require_participant
    return Viewer(researcher=False, participant=participant)


ViewerDep = Annotated[Viewer, Depends(get_viewer)]
