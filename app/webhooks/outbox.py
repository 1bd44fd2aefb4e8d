"""The transactional outbox: an event is written, one row per webhook of its study or survey,
in the caller's write transaction, the one that makes the change it reports. If that
transaction rolls back, no event was ever sent; once it commits, the event is delivered at
least once (:mod:`app.webhooks.delivery`) whatever happens to the process.

Cheap when nobody listens: one indexed ``SELECT`` of the collection's webhooks, and the
event's data (a callable) is computed only when there is one.

An event's id is derived from its webhook, type and *subject* (the participant it is
about), so writing the same event twice stores it once (``INSERT ... ON CONFLICT DO
NOTHING`` on the unique ``event_id``): a participant finishes once, a study reaches its
target once, whatever undo and concurrent writers do. An event without a subject (a
declined consent) gets a random id: each one is new.

Delivery does not keep order (:mod:`app.webhooks.scheduler`), so each event's body carries
its ``timestamp`` and ``seq``, its number among its study's (or survey's) events: one more
than the last event written for the collection's webhooks, the same for every webhook of the
collection, and increasing in the order the events were written. Writers of one collection's
events take turns on its webhooks' rows (``FOR NO KEY UPDATE`` on PostgreSQL; SQLite has one
writer at a time), so no two events share a number. A receiver may see gaps: numbers of
events written before it was registered, or sent once and not again (a target reached).
"""

from __future__ import annotations

import hashlib
import secrets
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from sqlalchemy import Connection, insert, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from app.models import Webhook, WebhookEvent, utcnow

#: Every event type, with what it reports (the README lists their data).
EVENT_TYPES = {
    "participant.finished": "a study participant finished their bracket",
    "participant.declined": "a visitor of a study's open link declined consent",
    "participant.flagged": "a participant was flagged (speed or position bias at finish, or "
    "the gold gate)",
    "study.target_reached": "a study's finished open-link participants reached its maximum",
    "respondent.finished": "a survey respondent answered every screen",
    "respondent.declined": "a visitor of a survey's open link declined consent",
    "survey.target_reached": "a survey's finished open-link respondents reached its maximum",
}
Data = dict[str, Any]


@dataclass(frozen=True)
class Owner:
    """The study or survey a webhook belongs to."""

    noun: Literal["study", "survey"]
    id: int

    @property
    def column(self) -> Any:
        """The webhooks column naming this owner (``study_id`` or ``survey_id``)."""
        return Webhook.study_id if self.noun == "study" else Webhook.survey_id

    def data(self) -> Data:
        """The owner as event data: ``{"study_id": 3}``."""
        return {f"{self.noun}_id": self.id}


def _connection(db: Session | Connection) -> Connection:
    return db.connection() if isinstance(db, Session) else db


def webhook_ids(db: Session | Connection, owner: Owner, *, lock: bool = False) -> list[int]:
    """The ids of the owner's webhooks, in order.

    Args:
        lock: hold their rows until the caller's transaction ends (PostgreSQL), so that the
            owner's event writers take turns.
    """
    query = select(Webhook.id).where(owner.column == owner.id).order_by(Webhook.id)
    if lock:
        query = query.with_for_update(key_share=True)  # FOR NO KEY UPDATE: events' keys stay free
    return list(_connection(db).scalars(query))


def last_seq(db: Session | Connection, ids: list[int]) -> int:
    """The ``seq`` of the last event written for these webhooks (0 for none)."""
    payload = _connection(db).scalar(
        select(WebhookEvent.payload)
        .where(WebhookEvent.webhook_id.in_(ids))
        .order_by(WebhookEvent.id.desc())
        .limit(1)
    )
    return int(payload.get("seq", 0)) if payload else 0


def event_id(webhook_id: int, type_: str, subject: str | None) -> str:
    """The id receivers deduplicate by: derived from the subject, random without one."""
    if subject is None:
        return f"evt_{secrets.token_hex(20)}"
    digest = hashlib.sha256(f"{webhook_id}:{type_}:{subject}".encode()).hexdigest()
    return f"evt_{digest[:40]}"


def emit(
    db: Session | Connection,
    *,
    owner: Owner,
    type_: str,
    subject: str | None,
    data: Callable[[], Data],
) -> int:
    """Write the event for each of the owner's webhooks, in the caller's transaction
    (never committed here); returns how many webhooks it was written for.

    Args:
        type_: one of :data:`EVENT_TYPES`.
        subject: what the event is about, stable across retries of the change (e.g. the
            participant's id); ``None``: every call is a new event.
        data: the event's data beyond the owner's id, called only if there is a webhook.
    """
    conn = _connection(db)
    ids = webhook_ids(conn, owner, lock=True)
    if not ids:
        return 0
    now = utcnow()
    payload = {
        "type": type_,
        "timestamp": now.isoformat(),
        "seq": last_seq(conn, ids) + 1,
        "data": owner.data() | data(),
    }
    rows = [
        {
            "webhook_id": webhook_id,
            "event_id": event_id(webhook_id, type_, subject),
            "type": type_,
            "payload": payload,
            "created_at": now,
            "attempts": 0,
            "next_attempt_at": now,
        }
        for webhook_id in ids
    ]
    conn.execute(_insert_once(conn), rows)
    return len(ids)


def _insert_once(conn: Connection) -> Any:
    """``INSERT`` that skips an event already stored (same ``event_id``)."""
    if conn.dialect.name == "postgresql":
        return postgresql.insert(WebhookEvent).on_conflict_do_nothing(index_elements=["event_id"])
    if conn.dialect.name == "sqlite":
        return sqlite.insert(WebhookEvent).on_conflict_do_nothing(index_elements=["event_id"])
    return insert(WebhookEvent)  # no other database is supported; kept plain
