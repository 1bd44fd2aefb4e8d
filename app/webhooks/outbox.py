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


def webhook_ids(db: Session | Connection, owner: Owner) -> list[int]:
    """The ids of the owner's webhooks."""
    return list(_connection(db).scalars(select(Webhook.id).where(owner.column == owner.id)))


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
    ids = webhook_ids(conn, owner)
    if not ids:
        return 0
    now = utcnow()
    payload = {"type": type_, "timestamp": now.isoformat(), "data": owner.data() | data()}
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
