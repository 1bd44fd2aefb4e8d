"""Recruiting through an open link, written once for both kinds of collection (issues 14 and
26): a study's ``/s/<slug>`` (:data:`app.studies.crowd.LINK`) and a survey's ``/q/<slug>``
(:data:`app.surveys.crowd.LINK`).

A new visitor joins as a member of their own, a returning one resumes (their cookie, or their
first external id with the per-attempt ids), a declined consent is only counted, and a member
who came through the link and finished gets its completion code. The seat count, the options
and the external ids are :mod:`app.recruiting.links`; whom a cookie names is
:func:`app.recruiting.members.resolve`. What differs between the kinds is a :class:`MemberKind`.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.auth import new_token
from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import OpenLink
from app.models.base import utcnow
from app.recruiting import events, links, members, seats
from app.recruiting.kinds import Link, MemberKind, full_message
from app.recruiting.links import LinkOptions
from app.recruiting.members import MemberRow, link_of
from engine.errors import InputError


def settings(
    session: Session, kind: MemberKind[Link, MemberRow], owner_id: int, *, for_update: bool = False
) -> Link | None:
    """The collection's open link and options, or ``None`` when never set; ``for_update``:
    read afresh and locked, inside the caller's write transaction."""
    query = select(kind.link).where(link_of(kind.members.noun, owner_id))
    if for_update:
        query = query.with_for_update().execution_options(populate_existing=True)
    return session.scalar(query)


def configured(session: Session, kind: MemberKind[Link, MemberRow], owner_id: int) -> Link:
    """The collection's open link and options.

    Raises:
        NotFoundError: never set.
    """
    link = settings(session, kind, owner_id)
    if link is None:
        raise NotFoundError(f"{kind.members.noun} {owner_id} has no open link")
    return link


def configure(
    session: Session, kind: MemberKind[Link, MemberRow], owner_id: int, options: LinkOptions
) -> Link:
    """Set the collection's open link and options (the slug is made once and kept); a
    subclass's options (a study's quality checks) are stored too, checked by the caller.

    Raises:
        InputError: a bad option, or a maximum below the people already joined.
        NotFoundError, ConflictError: no such collection, or it cannot take people now.
    """
    links.check_options(options)
    if options.time_limit_min is not None and not kind.timed:
        raise InputError(f"a {kind.members.noun}'s open link takes no time_limit_min")
    kind.check_collection(session, owner_id)
    return links.save(
        session,
        lambda: settings(session, kind, owner_id, for_update=True),
        lambda: kind.link(collection_id=owner_id),
        options,
    )


def open_link(session: Session, kind: MemberKind[Link, MemberRow], slug: str) -> Link:
    """The open link ``slug``, open or closed (:func:`links.find`).

    Raises:
        NotFoundError: no such link.
    """
    return links.find(session, kind.link, slug=slug, what=kind.members.noun)


def external_ids(link: OpenLink, query: dict[str, str]) -> dict[str, str]:
    """The link's external parameters found in ``query`` (see :func:`links.external_ids`)."""
    return links.external_ids(link.external_params, query)


def returning(
    session: Session,
    kind: MemberKind[Link, MemberRow],
    *,
    link: Link,
    ids: dict[str, str],
    token: str | None,
) -> MemberRow | None:
    """The member this visitor already is (:func:`links.returning`): by the cookie the
    browser holds for this collection, or by the first external id with the per-attempt ids;
    ``None`` for a new visitor.

    Raises:
        AlreadyTookPartError: the external id joined before, from another browser.
    """
    return links.returning(
        session,
        kind.members,
        owner_id=link.collection_id,
        params=link.external_params,
        ids=ids,
        token=token,
    )


def join(
    session: Session,
    kind: MemberKind[Link, MemberRow],
    *,
    link: Link,
    ids: dict[str, str],
    share: bool = False,
    join_key: str | None = None,
) -> MemberRow:
    """A new member for this visitor, or the one their first external id or the consent
    form's ``join_key`` names (two first visits of one id, or two posts of one form, at once:
    the members' unique indexes of collection and external id or join key settle it).
    ``share``: they agreed to have their labels shared in a public dataset (off unless they
    ticked it on the consent page).

    Raises:
        LinkClosedError: the researcher closed the link.
        LinkFullError: ``kind.full_error``, when the link has its largest number of people.
    """
    links.check_open(link, what=kind.members.noun)
    owner_id, now = link.collection_id, utcnow()
    kind.check_collection(session, owner_id)
    person = kind.members.member(
        collection_id=owner_id,
        deadline_at=seats.deadline(link, now),
        token=new_token(),
        external_id=ids.get(link.external_params[0]),
        external_ids=ids or None,
        via_link=True,
        share_consent=share,
        join_key=join_key,
    )
    try:
        with writing(session):
            full = kind.full_error(": ".join(full_message(kind)))
            seats.free_expired_seats(session, link, now)
            links.take_seat(session, link_of(kind.members.noun, owner_id), full=full)
            kind.stage(session, person)
    except IntegrityError:  # the same external id or form joined just before: resume it
        existing = returning(session, kind, link=link, ids=ids, token=None)
        if existing is None and join_key is not None:
            existing = members.member_by_join_key(
                session, kind.members, collection_id=owner_id, join_key=join_key
            )
        if existing is None:
            raise
        return existing
    return person


def has_room(session: Session, link: OpenLink) -> bool:
    """Whether ``link`` has a seat for a newcomer, once the seats of members past their time
    are given back (a write only when it is full and has a time limit)."""
    if not links.is_full(link) or link.time_limit_min is None:
        return not links.is_full(link)
    with writing(session):
        seats.free_expired_seats(session, link, utcnow())
    session.refresh(link)
    return not links.is_full(link)


def decline(session: Session, kind: MemberKind[Link, MemberRow], *, link: Link) -> None:
    """Count a declined consent, and write its webhook event in the same transaction;
    nothing else about the visitor is stored."""
    owner_id = link.collection_id
    with writing(session):
        links.count_decline(session, link_of(kind.members.noun, owner_id))
        events.declined(session, kind, owner_id=owner_id)


def outcome(
    session: Session,
    kind: MemberKind[Link, MemberRow],
    *,
    member: MemberRow,
    failed_gate: bool = False,
) -> tuple[seats.Outcome, seats.Ending | None]:
    """What became of ``member`` (:func:`app.recruiting.seats.outcome`), and the code and
    redirect they are shown for it (``None`` while in progress, or for an invited member)."""
    link = settings(session, kind, member.collection_id) if member.via_link else None
    result = seats.outcome(member, link, utcnow(), failed_gate=failed_gate)
    return result, seats.ending(link, result)


def completion(
    session: Session, kind: MemberKind[Link, MemberRow], *, member: MemberRow
) -> seats.Ending | None:
    """The code and redirect a finished open-link member gets; ``None`` before they finish,
    or for an invited member (the code is what a crowd platform pays against)."""
    result, shown = outcome(session, kind, member=member)
    return shown if result.name == "finished" else None


def withdraw(
    session: Session, kind: MemberKind[Link, MemberRow], *, member: MemberRow
) -> seats.Ending | None:
    """``member`` withdraws (:func:`app.recruiting.seats.withdraw`): their seat is freed and
    their answers left out of everything; the code and redirect they are shown.

    Raises:
        ConflictError: they finished (only the researcher can take their answers out).
        MemberEndedError: they ran out of time, or withdrew before.
    """
    if member.finished_at is not None:
        raise ConflictError(
            f"a finished {kind.members.person} cannot withdraw here; ask the researcher"
        )
    link = settings(session, kind, member.collection_id)
    with writing(session):
        if not seats.withdraw(session, member, link, utcnow()):
            raise seats.MemberEndedError(f"this {kind.members.person} can no longer withdraw here")
    session.refresh(member)
    return outcome(session, kind, member=member)[1]
