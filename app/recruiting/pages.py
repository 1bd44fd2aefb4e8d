"""The open-link pages, written once for studies (``/s/<slug>``), surveys (``/q/<slug>``)
and evaluations (``/e/<slug>``): consent (or a start button), a member per new visitor who
agrees (rate-limited), resume, "this ... is full", declined; and the researcher's open-link
form. :func:`open_link_router` builds them for one kind of collection (:class:`LinkPages`).

Only a ``POST`` makes a member: link previewers and mail scanners fetch links, and must not
take seats. Joining is rate-limited per client address (:mod:`app.http.ratelimit`, the same
moving window as failed logins, with its own counts, one for every kind of link); only
visits that create a person count.
"""

from __future__ import annotations

import re
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar
from urllib.parse import parse_qsl

from fastapi import APIRouter, Request, Response
from pydantic import BaseModel, ValidationError
from sqlalchemy.orm import Session

from app.core.errors import TooManyAttemptsError
from app.core.json_types import form_int
from app.http.cookies import set_member_cookie
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import SessionDep
from app.http.ratelimit import client_address
from app.http.rendering import PageRoute, is_https, redirect, render
from app.models import CrowdSettings, EvaluationLink, SurveyCrowdSettings
from app.recruiting import seats
from app.recruiting import service as recruiting
from app.recruiting.kinds import Link, MemberKind, full_message, open_path
from app.recruiting.links import DEFAULT_EXTERNAL_PARAMS, check_open
from app.recruiting.members import MemberRow
from engine.errors import InputError

T = TypeVar("T")
M = TypeVar("M", bound=BaseModel)
#: The consent form's one-time key (:attr:`app.models.Member.join_key`): 16 random bytes.
JOIN_KEY_BYTES = 16
JOIN_KEY = re.compile(r"[A-Za-z0-9_-]{22}")
#: The open-link forms' checkboxes (a browser sends ``on`` for a ticked one, nothing else).
CHECKBOXES = ("enabled", "consistency_check", "gate_excludes")
DECLINED = "You declined to take part; nothing about you was stored. You can close this page."


def admit(request: Request, join: Callable[[], T]) -> T:
    """``join()`` (make a new person through an open link), unless this client address made
    too many in the last minute.

    Raises:
        TooManyAttemptsError: 429 with Retry-After.
    """
    limiter, address = request.app.state.join_limiter, client_address(request)
    if limiter.blocked(address):
        raise TooManyAttemptsError(
            "Too many new participants from this address; try again in a minute.",
            retry_after_s=limiter.retry_after_s(address),
        )
    person = join()
    limiter.failed(address)  # counts a join
    return person


def query(request: Request) -> dict[str, str]:
    """The query's parameters (the last of a repeated name), bytes that are not UTF-8 kept as
    lone surrogates, so :func:`app.recruiting.links.external_ids` refuses them: decoded
    with replacement characters, as Starlette does, distinct raw ids would collide."""
    raw = request.scope["query_string"].decode("utf-8", "surrogateescape")
    return dict(parse_qsl(raw, keep_blank_values=True, errors="surrogateescape"))


def message(
    request: Request,
    name: str,
    title: str,
    text: str,
    status_code: int = 200,
    ending: seats.Ending | None = None,
) -> Response:
    """A plain page under the study's or survey's ``name``: full, declined, ...; ``ending``:
    the code and way back to the platform it shows."""
    return render(
        request,
        "member_message.html",
        {"header_name": name, "title": title, "text": text, "ending": ending},
        status_code=status_code,
    )


def consent(
    request: Request,
    name: str,
    link: CrowdSettings | SurveyCrowdSettings | EvaluationLink,
    action: str,
    ids: dict[str, str],
    share_label: str | None = None,
) -> Response:
    """The consent page: the researcher's text, agree or decline (posted to ``action``), or
    only a start button where the link has no consent text; and the optional, unticked
    choice to share (``share_label``, where the kind asks it)."""
    return render(
        request,
        "crowd_consent.html",
        {
            "header_name": name,
            "link": link,
            "action": action,
            "ids": ids,
            "share_label": share_label,
            "join_key": secrets.token_urlsafe(JOIN_KEY_BYTES),
        },
    )


def link_form(fields: dict[str, str]) -> dict[str, Any]:
    """The open-link fields of a researcher's form, as the API's body would hold them."""
    text = {
        k: fields.get(k, "").strip() or None
        for k in ("consent_text", "completion_code", "redirect_url", "decline_code")
    }
    params = [p.strip() for p in fields.get("external_params", "").split(",") if p.strip()]
    return {
        "enabled": fields.get("enabled") == "on",
        "max_participants": whole(fields, "max_participants"),
        "external_params": params or list(DEFAULT_EXTERNAL_PARAMS),
        **text,
    }


def form_echo(fields: dict[str, str]) -> dict[str, Any]:
    """A researcher's open-link form as it was posted, to show it again beside what was wrong
    (``templates/_open_link_form.html`` reads it as it reads saved options): ticked boxes
    stay ticked, and the typed text stays as typed."""
    echo: dict[str, Any] = dict(fields) | {k: True for k in CHECKBOXES if fields.get(k) == "on"}
    params = fields.get("external_params", "").split(",")
    echo["external_params"] = [p.strip() for p in params if p.strip()]
    return echo


def validated(schema: type[M], data: dict[str, Any]) -> M:
    """``data`` validated like the API's body; the first error as an :class:`InputError`."""
    try:
        return schema.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        raise InputError(f"{'.'.join(map(str, first['loc']))}: {first['msg']}") from None


def whole(fields: dict[str, str], name: str) -> int:
    found = form_int(fields.get(name, ""))
    if found is None:
        raise InputError(f"{name} must be a whole number")
    return found


@dataclass(frozen=True)
class LinkPages(Generic[Link, MemberRow]):
    """What the open-link pages of one kind of collection need beyond its :class:`MemberKind`."""

    kind: MemberKind[Link, MemberRow]
    #: The collection's name, shown in the page header (by its id).
    name_of: Callable[[Session, int], str]
    #: Where a member goes once they joined or resumed: their next page.
    next_path: Callable[[Session, MemberRow], str]
    #: The consent page's optional checkbox to share one's answers in a public dataset
    #: (its label), or ``None`` where the kind's answers are never shared.
    share_label: str | None = None

    def name(self, session: Session, link: Link) -> str:
        return self.name_of(session, link.collection_id)

    def full(self, request: Request, session: Session, link: Link) -> Response:
        """The page a visitor sees past the link's largest number of people."""
        title, text = full_message(self.kind)
        return message(request, self.name(session, link), title, text)


def open_link_router(pages: LinkPages[Link, MemberRow]) -> APIRouter:
    """The open link's two routes: ``GET`` (consent or start, or a returning member straight
    on) and ``POST`` (the form's agree, start or decline)."""
    router = APIRouter(route_class=PageRoute, include_in_schema=False)
    kind, path = pages.kind, pages.kind.prefix + "{slug}"

    @router.get(path)
    def open_link(slug: str, request: Request, session: SessionDep) -> Response:
        """A returning member goes on where they are; a new visitor gets the consent page
        (or a start button where the link has no consent text), "full" past the maximum.
        A ``GET`` never makes a member: a link previewer or a mail scanner that fetches the
        link must not take a seat."""
        link = recruiting.open_link(session, kind, slug)
        ids = recruiting.external_ids(link, query(request))
        person = _returning(kind, request, session, link, ids)
        if person is not None:
            return _enter(pages, request, session, link, ids, person)
        check_open(link, what=kind.members.noun)
        if not recruiting.has_room(session, link):
            return pages.full(request, session, link)
        name, action = pages.name(session, link), open_path(kind, link.slug)
        return consent(request, name, link, action, ids, pages.share_label)

    @router.post(path, dependencies=[CsrfChecked])
    def agree_or_decline(
        slug: str, request: Request, session: SessionDep, fields: FormFields
    ) -> Response:
        """Agree (a member is made) or decline (only the count of declines grows); one who
        is a member already (a second tab, the back button) goes on where they are."""
        link = recruiting.open_link(session, kind, slug)
        ids = recruiting.external_ids(link, fields)
        person = _returning(kind, request, session, link, ids)
        decision = fields.get("decision")
        if decision not in ("agree", "decline"):
            raise InputError("decision must be agree or decline")
        if decision == "decline" and person is None:
            recruiting.decline(session, kind, link=link)
            ending = seats.ending(link, seats.Outcome("withdrawn", link.decline_code))
            name = pages.name(session, link)
            return message(request, name, "You declined", DECLINED, ending=ending)
        share = (
            decision == "agree" and pages.share_label is not None and fields.get("share") == "on"
        )
        key = fields.get("join_key", "")
        join_key = key if JOIN_KEY.fullmatch(key) else None  # none: joins, never resumes
        return _enter(pages, request, session, link, ids, person, share=share, join_key=join_key)

    return router


def _returning(
    kind: MemberKind[Link, MemberRow],
    request: Request,
    session: Session,
    link: Link,
    ids: dict[str, str],
) -> MemberRow | None:
    """The member this visitor already is (by their cookie or first external id), or None."""
    token = request.cookies.get(kind.members.cookie)
    return recruiting.returning(session, kind, link=link, ids=ids, token=token)


def _enter(
    pages: LinkPages[Link, MemberRow],
    request: Request,
    session: Session,
    link: Link,
    ids: dict[str, str],
    person: MemberRow | None,
    share: bool = False,
    join_key: str | None = None,
) -> Response:
    """Resume ``person`` (a returning visitor), or make a member of a new one (rate-limited;
    ``share``: they agreed to share their answers; ``join_key``: the consent form's, whose
    second post resumes them); "full" past the maximum. Their cookie is set on the way to
    their next page."""
    kind = pages.kind
    if person is None:
        try:
            person = admit(
                request,
                lambda: recruiting.join(
                    session, kind, link=link, ids=ids, share=share, join_key=join_key
                ),
            )
        except kind.full_error:
            return pages.full(request, session, link)
    response = redirect(pages.next_path(session, person))
    set_member_cookie(response, kind.members, token=person.token, secure=is_https(request))
    return response
