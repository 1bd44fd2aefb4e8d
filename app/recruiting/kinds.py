"""What differs between the kinds of collection an open link recruits for (a study's
``/s/<slug>``, a survey's ``/q/<slug>``, an evaluation's ``/e/<slug>``), as the people layer
needs to know it: :class:`MemberKind`, the one small protocol each kind implements in its own
feature package (:class:`app.labelling.study_link.StudyKind`, :class:`app.surveys.crowd.SurveyKind`,
:class:`app.evaluations.crowd.EvaluationKind`). Below the service and the events
(:mod:`app.recruiting.service`, :mod:`app.recruiting.events`), which both take one; what is
the same for every kind (the "full" page's text, the link's path and URL) is written once here,
as functions of a kind; the condition on its row is :func:`app.recruiting.members.link_of`."""

from __future__ import annotations

from typing import Protocol

from sqlalchemy.orm import Session

from app.recruiting.links import Link, LinkFullError
from app.recruiting.members import CollectionKind, MemberRow


class MemberKind(Protocol[Link, MemberRow]):
    """A kind of collection as its open link needs it: static data as class attributes, and
    what a collection and a new member of it take.

    Attributes:
        members: The collection's name (``members.noun``: ``study``) and its members' (the
            member table, invite path and cookie).
        link: The open link's table (its model).
        prefix: The open link's path is this prefix and its slug (``/s/``, ``/q/``).
        full_error: The error raised when every seat is taken.
        timed: Whether its members can run out of time (a study's bracket; a survey's
            screens take no time limit).
    """

    members: CollectionKind[MemberRow]
    link: type[Link]
    prefix: str
    full_error: type[LinkFullError]
    timed: bool

    def check_collection(self, session: Session, collection_id: int) -> None:
        """Refuse (raise) a collection that cannot take people now: a study not ready yet.

        Raises:
            NotFoundError, ConflictError: no such collection, or it cannot take people now.
        """
        ...

    def stage(self, session: Session, member: MemberRow) -> None:
        """Add a new member, with what they start with, inside the join's write
        transaction (a participant's first round of matches, an evaluator's pairs)."""
        ...


def full_message(kind: MemberKind[Link, MemberRow]) -> tuple[str, str]:
    """What a visitor is told when every seat is taken: a title and a sentence."""
    noun = kind.members.noun
    return (
        f"This {noun} is full",
        f"This {noun} has all the {kind.members.people} it needs. Thank you for your interest.",
    )


def open_path(kind: MemberKind[Link, MemberRow], slug: str) -> str:
    """The path of the open link ``slug``."""
    return f"{kind.prefix}{slug}"


def open_url(kind: MemberKind[Link, MemberRow], base_url: object, slug: str) -> str:
    """The open link ``slug`` under ``base_url`` (a request's, e.g. ``http://host/``)."""
    return str(base_url).rstrip("/") + open_path(kind, slug)
