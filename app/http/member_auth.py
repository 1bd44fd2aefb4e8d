"""Members' credentials as FastAPI dependencies: a study's participants, a survey's
respondents and an evaluation's evaluators each send their invite token as
``Authorization: Bearer <token>`` (each kind its own security scheme in ``/docs``) or carry
the cookie their invite link set; all are resolved by the one lookup,
:func:`app.recruiting.members.resolve`.

The ``*_gate`` functions make the same checks on a request whose body is not read yet
(:mod:`app.http.credentials_first`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated

import anyio.to_thread
from fastapi import Cookie, Depends, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.core import auth
from app.http.deps import (
    BearerCredentials,
    SessionDep,
    bearer_value,
    check_cookie_write,
    invite_bearer,
)
from app.models import Evaluator, SurveyRespondent
from app.recruiting import members
from app.runtime import Runtime


async def invite_token(
    request: Request,
    credentials: Annotated[BearerCredentials, Depends(invite_bearer)],
    cookie: Annotated[str | None, Cookie(alias=auth.PARTICIPANT_COOKIE)] = None,
) -> str | None:
    """The invite token sent (bearer first, then the cookie), not yet checked."""
    if (token := bearer_value(credentials)) is not None:
        return token
    if cookie:
        check_cookie_write(request)
    return cookie


#: The unchecked invite token, for hot paths that check it in their own worker thread
#: (``members.participant_ref``) rather than in a thread hop of its own.
InviteTokenDep = Annotated[str | None, Depends(invite_token)]


def require_participant(session: SessionDep, token: InviteTokenDep) -> members.ParticipantRef:
    """The participant whose invite token is sent (known tokens without a query), or 401."""
    participant = members.participant_ref(session, token=token)
    session.commit()  # hand the connection back while the request waits for the handler
    return participant


ParticipantDep = Annotated[members.ParticipantRef, Depends(require_participant)]


async def participant_gate(request: Request) -> None:
    """:func:`require_participant`, on a request whose body is not read yet
    (:mod:`app.http.credentials_first`); a token this process knows needs no thread hop,
    which keeps the labelling hot path as it was."""
    token = await invite_token(
        request, await invite_bearer(request), request.cookies.get(auth.PARTICIPANT_COOKIE)
    )
    runtime: Runtime = request.app.state.runtime
    if not members.known(runtime.engine, members.STUDY, token=token):
        await anyio.to_thread.run_sync(_check_participant, runtime, token)


def _check_participant(runtime: Runtime, token: str | None) -> None:
    with runtime.engine.connect() as conn:
        members.participant_ref(conn, token=token)


def _member(
    request: Request,
    session: Session,
    kind: members.CollectionKind[members.MemberRow],
    credentials: HTTPAuthorizationCredentials | None,
    cookie: str | None,
) -> members.MemberRow:
    """The member of ``kind`` whose invite token is sent (bearer first, then the cookie),
    or 401."""
    token = credentials.credentials if credentials is not None else cookie
    if credentials is None and cookie:
        check_cookie_write(request)
    person = members.member_by_token(session, kind, token=token)
    session.commit()
    return person


async def _member_gate(
    request: Request,
    bearer: HTTPBearer,
    kind: members.CollectionKind[members.MemberRow],
    require: Callable[..., object],
) -> None:
    """A member kind's dependency ``require``, on a request whose body is not read yet
    (:mod:`app.http.credentials_first`): a query in a worker thread, once per screen."""
    credentials = await bearer(request)
    runtime: Runtime = request.app.state.runtime

    def check(cookie: str | None) -> None:
        with runtime.sessions() as session:
            require(request, session, credentials, cookie)

    await anyio.to_thread.run_sync(check, request.cookies.get(kind.cookie))


_respondent_bearer = HTTPBearer(
    auto_error=False,
    scheme_name="SurveyInviteToken",
    description="A survey respondent's invite token.",
)
RespondentCredentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_respondent_bearer)]
RespondentCookie = Annotated[str | None, Cookie(alias=members.SURVEY.cookie)]


def require_respondent(
    request: Request,
    session: SessionDep,
    credentials: RespondentCredentials,
    cookie: RespondentCookie = None,
) -> SurveyRespondent:
    """The respondent whose invite token is sent (bearer first, then the cookie), or 401."""
    return _member(request, session, members.SURVEY, credentials, cookie)


RespondentDep = Annotated[SurveyRespondent, Depends(require_respondent)]


async def respondent_gate(request: Request) -> None:
    """:func:`require_respondent` before the body is read."""
    await _member_gate(request, _respondent_bearer, members.SURVEY, require_respondent)


_evaluator_bearer = HTTPBearer(
    auto_error=False,
    scheme_name="EvaluatorInviteToken",
    description="An agent evaluation's evaluator's invite token.",
)
EvaluatorCredentials = Annotated[HTTPAuthorizationCredentials | None, Depends(_evaluator_bearer)]
EvaluatorCookie = Annotated[str | None, Cookie(alias=members.EVALUATION.cookie)]


def require_evaluator(
    request: Request,
    session: SessionDep,
    credentials: EvaluatorCredentials,
    cookie: EvaluatorCookie = None,
) -> Evaluator:
    """The evaluator whose invite token is sent (bearer first, then the cookie), or 401."""
    return _member(request, session, members.EVALUATION, credentials, cookie)


EvaluatorDep = Annotated[Evaluator, Depends(require_evaluator)]


async def evaluator_gate(request: Request) -> None:
    """:func:`require_evaluator` before the body is read."""
    await _member_gate(request, _evaluator_bearer, members.EVALUATION, require_evaluator)
