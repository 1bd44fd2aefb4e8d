"""Open links (issue 14), shared by studies (``/s/<slug>``, :mod:`app.studies.crowd`) and
surveys (``/q/<slug>``, :mod:`app.surveys.crowd`): the options, the external ids a
crowd platform appends, and the seat count.

Each new visitor of an open link becomes a person of their own. ``joined`` on the link's
row is incremented by one ``UPDATE ... WHERE joined < max_participants`` in the same
transaction that creates the person (:func:`take_seat`), so concurrent first visits never
pass the maximum (the row lock on PostgreSQL, the single writer on SQLite, and a CHECK
constraint behind both).
"""

from __future__ import annotations

import contextlib
import re
import secrets
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from sqlalchemy import ColumnElement, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core import atomic
from app.core.errors import AuthError, ConflictError, NotFoundError, ServiceError
from app.core.limits import check_text
from app.db import writing
from app.models import (
    CrowdSettings,
    EvaluationLink,
    OpenLink,
    SurveyCrowdSettings,
)
from app.recruiting import members
from app.recruiting.members import CollectionKind, MemberRow
from engine.errors import InputError

DEFAULT_EXTERNAL_PARAMS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
MAX_PARTICIPANTS = 100_000
#: The longest time limit an open link takes: a week, in minutes (Prolific's longest study
#: time is shorter; set the link's limit at or below the platform's).
MAX_TIME_LIMIT_MIN = 10_080
MAX_EXTERNAL_CHARS = 200
_PARAM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
#: Where an open link may send people: an http(s) URL (the API documents this pattern, and
#: the forms check it here). ECMA-262 and Rust regex syntax both: no inline flags.
REDIRECT_URL_PATTERN = r"^[Hh][Tt][Tt][Pp][Ss]?://[^\s/?#][^\s]*$"

#: Unicode categories an external id must not hold: control, format, line and paragraph
#: separators, and lone surrogates (bytes that were not UTF-8, see :func:`external_ids`).
_UNPRINTABLE = frozenset({"Cc", "Cf", "Zl", "Zp", "Cs"})
ALREADY_TOOK_PART = (
    "This id has already taken part, from another browser. If it is yours, go back to the "
    "browser you started in, or open the link from your study platform again."
)

Link = TypeVar("Link", CrowdSettings, SurveyCrowdSettings, EvaluationLink)


class LinkFullError(ConflictError):
    """The open link reached its largest number of people."""


class LinkClosedError(ServiceError):
    """The researcher closed the open link: it takes no new people (410); those who joined
    before go on (their cookie resumes them, their token still works)."""

    status_code = 410
    title = "This link is closed"


class AlreadyTookPartError(ConflictError):
    """An external id that joined before, from a browser that is not theirs (409)."""

    title = "This id has already taken part"


@dataclass(frozen=True)
class LinkOptions:
    """What the researcher sets for an open link."""

    enabled: bool = False
    max_participants: int = 100
    external_params: tuple[str, ...] = DEFAULT_EXTERNAL_PARAMS
    consent_text: str | None = None
    completion_code: str | None = None
    redirect_url: str | None = None
    time_limit_min: int | None = None
    decline_code: str | None = None


def check_options(options: LinkOptions) -> None:
    """Refuse a bad option with an :class:`InputError` that names it."""
    if not 1 <= options.max_participants <= MAX_PARTICIPANTS:
        raise InputError(f"max_participants must be in 1..{MAX_PARTICIPANTS}")
    if not 1 <= len(options.external_params) <= 10 or not all(
        _PARAM_NAME.fullmatch(p) for p in options.external_params
    ):
        raise InputError("external_params must be 1..10 names of letters, digits and _")
    if len(set(options.external_params)) != len(options.external_params):
        raise InputError("external_params must not repeat a name")
    if options.redirect_url is not None and not re.fullmatch(
        REDIRECT_URL_PATTERN, options.redirect_url
    ):
        raise InputError("redirect_url must be an http(s) URL")
    if options.time_limit_min is not None and not 1 <= options.time_limit_min <= MAX_TIME_LIMIT_MIN:
        raise InputError(f"time_limit_min must be in 1..{MAX_TIME_LIMIT_MIN} (minutes)")
    check_text(
        consent_text=options.consent_text,
        completion_code=options.completion_code,
        redirect_url=options.redirect_url,
        decline_code=options.decline_code,
    )


def save(
    session: Session,
    current: Callable[[], Link | None],
    make: Callable[[], Link],
    options: LinkOptions,
) -> Link:
    """Store ``options`` (those of a subclass too) on the collection's link (``current``
    finds it), or on a new one from ``make`` with a fresh slug (kept afterwards).

    The link is read inside the write transaction, locked, so a join cannot slip under a
    lowered maximum; two first saves at once meet at the unique index, and the one that
    loses stores its options on the other's link.

    Raises:
        InputError: a maximum below the people who already joined.
    """
    try:
        with writing(session):
            return _store(session, current(), make, options)
    except IntegrityError:  # the link was made meanwhile: it is there now, so update it
        with writing(session):
            return _store(session, current(), make, options)


def _store(
    session: Session, row: Link | None, make: Callable[[], Link], options: LinkOptions
) -> Link:
    """Put ``options`` on ``row`` (or on a new link), inside the caller's transaction."""
    if row is None:
        row = make()
        row.slug, row.joined, row.declines = secrets.token_urlsafe(9), 0, 0
    elif options.max_participants < row.joined:
        raise InputError(f"max_participants must be at least the {row.joined} who already joined")
    for field, value in vars(options).items():
        setattr(row, field, list(value) if field == "external_params" else value)
    session.add(row)
    return row


def find(session: Session, model: type[Link], *, slug: str, what: str) -> Link:
    """The open link ``slug`` of ``model``'s table, open or closed (a closed one still
    resumes the people who joined; :func:`check_open` turns new ones away).

    Raises:
        NotFoundError: no such link.
    """
    row = session.scalar(select(model).where(model.slug == slug)) if len(slug) <= 64 else None
    if row is None:
        raise NotFoundError(f"There is no such {what} link. Check the link, or ask the researcher.")
    return row


def check_open(link: OpenLink, *, what: str) -> None:
    """Refuse a new person on a closed link, as Prolific does with a paused or completed study:
    closing stops new people joining, and those already in can finish.

    Raises:
        LinkClosedError: the researcher closed the link.
    """
    if not link.enabled:
        raise LinkClosedError(
            f"This {what} is closed: it is not taking new people. If you already started, "
            "open the link in the browser you started in."
        )


def external_ids(params: list[str], query: dict[str, str]) -> dict[str, str]:
    """The parameters ``params`` found in ``query`` (trimmed, at most 200 characters).

    Raises:
        InputError: a value is too long, or holds a control or format character, a line or
            paragraph separator, or a lone surrogate (a query decoded with
            ``surrogateescape``, whose bytes were not UTF-8).
    """
    found = {}
    for name in params:
        raw = query.get(name, "")
        value = raw.strip(" ")  # before any other strip: str.strip() drops U+0085 and U+2028
        if len(value) > MAX_EXTERNAL_CHARS or any(
            unicodedata.category(c) in _UNPRINTABLE for c in raw
        ):
            raise InputError(
                f"{name} must be at most {MAX_EXTERNAL_CHARS} printable characters of UTF-8"
            )
        if value:
            found[name] = value
    return found


def returning(
    session: Session,
    kind: CollectionKind[MemberRow],
    *,
    owner_id: int,
    params: list[str],
    ids: dict[str, str],
    token: str | None,
) -> MemberRow | None:
    """The member of ``kind`` in the collection ``owner_id`` this visitor already is, or
    ``None`` for a new one.

    Without an external id, the member whose cookie ``token`` (checked by
    :func:`app.recruiting.members.member_by_token`) the browser holds. With one that joined
    before, that person only in the browser that joined (its cookie), or where every other
    external parameter (the platform's per-attempt ids, such as ``SESSION_ID``) was stored
    and matches: an id alone is public enough (it is in every URL the platform makes) that
    it must not hand over someone's session.

    Raises:
        AlreadyTookPartError: the id joined before, and neither the cookie nor the
            per-attempt ids say this is the same person.
    """
    cookie = None
    if token:  # a cookie of another collection, or no longer valid, is no cookie here
        with contextlib.suppress(AuthError):
            cookie = members.member_by_token(session, kind, token=token, collection_id=owner_id)
    key = ids.get(params[0])
    if key is None:
        return cookie
    known = members.member_by_external_id(session, kind, collection_id=owner_id, external_id=key)
    if known is None:
        return None
    if cookie is not None and cookie.id == known.id:
        return known
    if _same_attempt(params[1:], ids, known.external_ids or {}):
        return known
    raise AlreadyTookPartError(ALREADY_TOOK_PART)


def _same_attempt(params: list[str], ids: dict[str, str], stored: dict[str, str]) -> bool:
    """Every per-attempt id was stored at the first visit and comes back the same."""
    return bool(params) and all(
        p in stored
        and p in ids
        and secrets.compare_digest(ids[p].encode(), str(stored[p]).encode())
        for p in params
    )


def is_full(link: OpenLink) -> bool:
    return link.joined >= link.max_participants


def take_seat(session: Session, owner: ColumnElement[bool], *, full: LinkFullError) -> None:
    """Count one more person on the link ``owner`` selects, inside the caller's write
    transaction (atomic: ``UPDATE ... WHERE joined < max_participants``,
    :func:`app.core.atomic.take`).

    Raises:
        LinkFullError: ``full``, when every seat is taken.
    """
    if not atomic.take(session, OpenLink.joined, owner, limit=OpenLink.max_participants):
        raise full


def count_decline(session: Session, owner: ColumnElement[bool]) -> None:
    """Count a declined consent, inside the caller's write transaction; nothing else about
    the visitor is stored."""
    session.execute(update(OpenLink).where(owner).values(declines=OpenLink.declines + 1))
