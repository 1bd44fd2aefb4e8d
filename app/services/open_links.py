"""Open links (issue 14), shared by studies (``/s/<slug>``, :mod:`app.services.crowd`) and
surveys (``/q/<slug>``, :mod:`app.services.survey_crowd`): the options, the external ids a
crowd platform appends, and the seat count.

Each new visitor of an open link becomes a person of their own. ``joined`` on the link's
row is incremented by one ``UPDATE ... WHERE joined < max_participants`` in the same
transaction that creates the person (:func:`take_seat`), so concurrent first visits never
pass the maximum (the row lock on PostgreSQL, the single writer on SQLite, and a CHECK
constraint behind both).
"""

from __future__ import annotations

import re
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from sqlalchemy import ColumnElement, select, update
from sqlalchemy.orm import Session

from app.db import writing
from app.models import CrowdSettings, SurveyCrowdSettings
from app.services.errors import ConflictError, NotFoundError
from app.services.studies import check_text
from engine.errors import InputError

DEFAULT_EXTERNAL_PARAMS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
MAX_PARTICIPANTS = 100_000
MAX_EXTERNAL_CHARS = 200
_PARAM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")
#: Where an open link may send people: an http(s) URL (the API documents this pattern, and
#: the forms check it here). ECMA-262 and Rust regex syntax both: no inline flags.
REDIRECT_URL_PATTERN = r"^[Hh][Tt][Tt][Pp][Ss]?://[^\s/?#][^\s]*$"

Link = TypeVar("Link", CrowdSettings, SurveyCrowdSettings)


class LinkFullError(ConflictError):
    """The open link reached its largest number of people."""


@dataclass(frozen=True)
class LinkOptions:
    """What the researcher sets for an open link."""

    enabled: bool = False
    max_participants: int = 100
    external_params: tuple[str, ...] = DEFAULT_EXTERNAL_PARAMS
    consent_text: str | None = None
    completion_code: str | None = None
    redirect_url: str | None = None


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
    check_text(
        consent_text=options.consent_text,
        completion_code=options.completion_code,
        redirect_url=options.redirect_url,
    )


def save(
    session: Session, row: Link | None, make: Callable[[], Link], options: LinkOptions
) -> Link:
    """Store ``options`` (those of a subclass too) on the link ``row``, or on a new one from
    ``make`` with a fresh slug (kept afterwards).

    Raises:
        InputError: a maximum below the people who already joined.
    """
    if row is None:
        row = make()
        row.slug, row.joined, row.declines = secrets.token_urlsafe(9), 0, 0
    elif options.max_participants < row.joined:
        raise InputError(f"max_participants must be at least the {row.joined} who already joined")
    for field, value in vars(options).items():
        setattr(row, field, list(value) if field == "external_params" else value)
    with writing(session):
        session.add(row)
    return row


def find(session: Session, model: type[Link], *, slug: str, what: str) -> Link:
    """The enabled open link ``slug`` of ``model``'s table.

    Raises:
        NotFoundError: no such link, or the researcher closed it.
    """
    row = session.scalar(select(model).where(model.slug == slug)) if len(slug) <= 64 else None
    if row is None or not row.enabled:
        raise NotFoundError(f"This {what} link is not open. Check the link, or ask the researcher.")
    return row


def external_ids(params: list[str], query: dict[str, str]) -> dict[str, str]:
    """The parameters ``params`` found in ``query`` (trimmed, at most 200 characters).

    Raises:
        InputError: a value is too long or holds control characters.
    """
    found = {}
    for name in params:
        value = query.get(name, "").strip()
        if len(value) > MAX_EXTERNAL_CHARS or any(ord(c) < 32 for c in value):
            raise InputError(f"{name} must be at most {MAX_EXTERNAL_CHARS} printable characters")
        if value:
            found[name] = value
    return found


def is_full(link: CrowdSettings | SurveyCrowdSettings) -> bool:
    return link.joined >= link.max_participants


def take_seat(
    session: Session, model: type[Link], owner: ColumnElement[bool], *, full: LinkFullError
) -> None:
    """Count one more person on the link ``owner`` selects, inside the caller's write
    transaction (atomic: ``UPDATE ... WHERE joined < max_participants``).

    Raises:
        LinkFullError: ``full``, when every seat is taken.
    """
    taken = session.execute(
        update(model)
        .where(owner, model.joined < model.max_participants)
        .values(joined=model.joined + 1)
    ).rowcount  # type: ignore[attr-defined]
    if taken == 0:
        raise full


def count_decline(session: Session, model: type[Link], owner: ColumnElement[bool]) -> None:
    """Count a declined consent; nothing else about the visitor is stored."""
    with writing(session):
        session.execute(update(model).where(owner).values(declines=model.declines + 1))
