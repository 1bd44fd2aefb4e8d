"""What differs between the kinds of open link (a study's ``/s/<slug>``, a survey's
``/q/<slug>``), as the people layer needs to know it: :class:`LinkKind`. Below the service
and the events (:mod:`app.recruiting.service`, :mod:`app.recruiting.events`), which both
take one."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic

from sqlalchemy import ColumnElement, and_
from sqlalchemy.orm import Session

from app.models import OpenLink
from app.recruiting.links import Link, LinkFullError
from app.recruiting.members import CollectionKind, MemberRow


@dataclass(frozen=True)
class LinkKind(Generic[Link, MemberRow]):
    """A kind of collection's open link: its members, table and path, and what joining takes."""

    members: CollectionKind[MemberRow]
    link: type[Link]
    #: The link's path is this prefix and its slug (``/s/``, ``/q/``).
    prefix: str
    #: The error raised when every seat is taken.
    full_error: type[LinkFullError]
    #: Refuses (raises) a collection that cannot take people now: a study not ready yet.
    check_collection: Callable[[Session, int], object]
    #: Adds a new member inside the join's write transaction (a participant's first round
    #: of matches is made with them).
    stage: Callable[[Session, MemberRow], None]
    #: Whether its members can run out of time (a study's bracket; a survey's screens take
    #: no time limit).
    timed: bool = False

    @property
    def full(self) -> tuple[str, str]:
        """What a visitor is told when every seat is taken: a title and a sentence."""
        noun = self.members.noun
        return (
            f"This {noun} is full",
            f"This {noun} has all the {self.members.people} it needs. Thank you for your interest.",
        )

    def open_path(self, slug: str) -> str:
        """The path of the open link ``slug``."""
        return f"{self.prefix}{slug}"

    def open_url(self, base_url: object, slug: str) -> str:
        """The open link ``slug`` under ``base_url`` (a request's, e.g. ``http://host/``)."""
        return str(base_url).rstrip("/") + self.open_path(slug)

    def owner_is(self, owner_id: int) -> ColumnElement[bool]:
        """The condition that selects the link row of collection ``owner_id``."""
        return and_(
            OpenLink.collection_kind == self.members.noun, OpenLink.collection_id == owner_id
        )
