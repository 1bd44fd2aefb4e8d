"""Webhook events of the people layer, written once for studies and surveys (issue 29 §3):
a member finished (``participant.finished``, ``respondent.finished``) or was flagged
(``*.flagged``), a visitor of an open link declined consent (``*.declined``), and a
collection reached its target
(``study.target_reached``, ``survey.target_reached``): its finished open-link members
reached the link's maximum, the number of people the researcher wanted.

Each is written by :func:`app.webhooks.outbox.emit` inside the caller's write transaction,
the one that makes the change, and costs one indexed query when nobody listens.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

from sqlalchemy import Connection, func, select
from sqlalchemy.orm import Session

from app.models import Member, OpenLink
from app.recruiting.kinds import Link, MemberKind
from app.recruiting.members import MemberRow, link_of, of_collection
from app.webhooks.outbox import Data, Owner, emit, webhook_ids

DB = Session | Connection


def _connection(db: DB) -> Connection:
    return db.connection() if isinstance(db, Session) else db


#: The kinds of collection webhooks listen to (an agent evaluation has none), by noun.
WEBHOOK_OWNERS: dict[str, Literal["study", "survey"]] = {"study": "study", "survey": "survey"}


def owner(kind: MemberKind[Link, MemberRow], owner_id: int) -> Owner | None:
    """The study or survey ``owner_id`` of ``kind``, as webhooks name it; ``None`` for a kind
    no webhook listens to."""
    noun = WEBHOOK_OWNERS.get(kind.members.noun)
    return None if noun is None else Owner(noun, owner_id)


def declined(db: DB, kind: MemberKind[Link, MemberRow], *, owner_id: int) -> None:
    """A visitor declined consent (nothing about them is stored, so the event carries only
    the count of declines)."""
    if (own := owner(kind, owner_id)) is None:
        return
    conn = _connection(db)
    count = select(OpenLink.declines).where(link_of(kind.members.noun, owner_id))
    emit(
        conn,
        owner=own,
        type_=f"{kind.members.person}.declined",
        subject=None,
        data=lambda: {"declines": conn.scalar(count)},
    )


def finished(
    db: DB,
    kind: MemberKind[Link, MemberRow],
    *,
    member_id: int,
    owner_id: int,
    shown_id: int | None = None,
    extra: Callable[[], Data] = dict,
) -> None:
    """A member finished: ``<person>.finished`` with their external ids (and ``extra``),
    then the target event if their collection just reached it. ``shown_id`` is the id the
    event shows, where it is not ``member_id`` (a respondent renumbered by revision 0017:
    :attr:`app.models.SurveyRespondent.shown_id`).

    Call it only when the member has just been marked finished, in that transaction.
    """
    conn, own = _connection(db), owner(kind, owner_id)
    if own is None or not webhook_ids(conn, own):
        return
    # The link's row before the webhooks' rows (emit's turn), in the order a decline takes them
    maximum = _locked_maximum(conn, own)
    shown = member_id if shown_id is None else shown_id
    emit(
        conn,
        owner=own,
        type_=f"{kind.members.person}.finished",
        subject=str(shown),
        data=lambda: _member_data(conn, kind, member_id, shown) | extra(),
    )
    _target(conn, kind, own, maximum)


def flagged(
    db: DB, kind: MemberKind[Link, MemberRow], *, member_id: int, owner_id: int, by: str, data: Data
) -> None:
    """``<person>.flagged`` by ``by`` (``finish``, ``gold_gate``), sent once per member and
    ``by`` whatever number of times it is written."""
    if (own := owner(kind, owner_id)) is None:
        return
    emit(
        _connection(db),
        owner=own,
        type_=f"{kind.members.person}.flagged",
        subject=f"{member_id}:{by}",
        data=lambda: {f"{kind.members.person}_id": member_id, "by": by} | data,
    )


def _member_data(
    conn: Connection, kind: MemberKind[Link, MemberRow], member_id: int, shown_id: int
) -> Data:
    row = conn.execute(
        select(Member.external_id, Member.external_ids, Member.via_link, Member.finished_at).where(
            Member.id == member_id
        )
    ).one()
    return {
        f"{kind.members.person}_id": shown_id,
        "external_id": row.external_id,
        "external_ids": row.external_ids or {},
        "via_link": row.via_link,
        "finished_at": row.finished_at.isoformat() if row.finished_at else None,
    }


def _locked_maximum(conn: Connection, own: Owner) -> int | None:
    """The open link's maximum, its row locked until the transaction ends (PostgreSQL; SQLite
    has one writer anyway); ``None`` without a link."""
    return conn.scalar(
        select(OpenLink.max_participants).where(link_of(own.noun, own.id)).with_for_update()
    )


def _target(
    conn: Connection, kind: MemberKind[Link, MemberRow], own: Owner, maximum: int | None
) -> None:
    """``<noun>.target_reached`` once the finished open-link members reach the ``maximum``,
    once per maximum (raising it and reaching it again is a new event).

    The link's row is locked first (:func:`_locked_maximum`), so that of two members
    finishing at once the second counts the first: neither misses the target.
    """
    if maximum is None:
        return  # no open link: no target
    done = conn.scalar(
        select(func.count(Member.id)).where(
            of_collection(own.noun, own.id),
            Member.via_link.is_(True),
            Member.finished_at.is_not(None),
        )
    )
    if done is not None and done >= maximum:
        emit(
            conn,
            owner=own,
            type_=f"{kind.members.noun}.target_reached",
            subject=f"target:{maximum}",
            data=lambda: {"finished": done, "max_participants": maximum},
        )
