"""A study's or a survey's webhooks: register one (its URL checked, before any request, by
:mod:`app.webhooks.targets`), list, remove, and read its events and the log of every
delivery attempt."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any, cast

from sqlalchemy import ColumnElement, CursorResult, case, delete, func, select
from sqlalchemy.orm import InstrumentedAttribute, Session

from app.core import atomic
from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import Study, Survey, Webhook, WebhookAttempt, WebhookEvent, utcnow
from app.webhooks.outbox import Owner
from app.webhooks.signing import new_secret
from app.webhooks.targets import Targets, check_url

#: Webhooks one study or survey may have (counted in ``webhook_count`` of its row).
MAX_WEBHOOKS = 10
#: Attempts and events a listing returns at most, newest first.
MAX_LISTED = 500


@dataclass(frozen=True)
class Counts:
    """A webhook's events: delivered, still being retried, and given up."""

    delivered: int = 0
    pending: int = 0
    failed: int = 0


@dataclass(frozen=True)
class AttemptRow:
    """One delivery attempt, with the event it delivered."""

    id: int
    event_id: str
    type: str
    attempted_at: datetime
    status_code: int | None
    error: str | None
    duration_ms: int


def _check_owner(session: Session, owner: Owner) -> None:
    model = Study if owner.noun == "study" else Survey
    if session.get(model, owner.id) is None:
        raise NotFoundError(f"{owner.noun} {owner.id} not found")


def register(session: Session, *, owner: Owner, url: str, targets: Targets) -> Webhook:
    """A new webhook of ``owner`` with a fresh secret; nothing is sent to the URL.

    Raises:
        NotFoundError: no such study or survey.
        InputError: the URL is not https, or points at a refused address.
        ConflictError: the owner has :data:`MAX_WEBHOOKS` already.
    """
    _check_owner(session, owner)
    check_url(url, targets=targets)
    webhook = Webhook(url=url, secret=new_secret(), **owner.data())
    with writing(session):  # counted with the webhook: concurrent adds never pass the limit
        if not atomic.take(session, *_counter(owner), limit=MAX_WEBHOOKS):
            raise ConflictError(f"a {owner.noun} has at most {MAX_WEBHOOKS} webhooks")
        session.add(webhook)
    return webhook


def _counter(owner: Owner) -> tuple[InstrumentedAttribute[int], ColumnElement[bool]]:
    """The owner's webhook counter, and the condition that selects the owner's row."""
    model: type[Study] | type[Survey] = Study if owner.noun == "study" else Survey
    return model.webhook_count, model.id == owner.id


def list_webhooks(session: Session, *, owner: Owner | None = None) -> list[Webhook]:
    """The owner's webhooks (every webhook without one), oldest first.

    Raises:
        NotFoundError: no such study or survey.
    """
    query = select(Webhook).order_by(Webhook.id)
    if owner is not None:
        _check_owner(session, owner)
        query = query.where(owner.column == owner.id)
    return list(session.scalars(query))


def get_webhook(session: Session, *, webhook_id: int) -> Webhook:
    """Raises: NotFoundError: no such webhook."""
    webhook = session.get(Webhook, webhook_id)
    if webhook is None:
        raise NotFoundError(f"webhook {webhook_id} not found")
    return webhook


def owner_of(webhook: Webhook) -> Owner:
    """The study or survey ``webhook`` belongs to."""
    if webhook.study_id is not None:
        return Owner("study", webhook.study_id)
    return Owner("survey", int(webhook.survey_id or 0))


def remove(session: Session, *, webhook_id: int, owner: Owner | None = None) -> None:
    """Remove a webhook with its undelivered events and its log (nothing more is sent).

    Raises:
        NotFoundError: no such webhook (of ``owner``, when given).
    """
    webhook = get_webhook(session, webhook_id=webhook_id)
    if owner is not None and owner_of(webhook) != owner:
        raise NotFoundError(f"webhook {webhook_id} of {owner.noun} {owner.id} not found")
    with writing(session):
        gone = session.execute(delete(Webhook).where(Webhook.id == webhook_id))
        if not cast(CursorResult[Any], gone).rowcount:  # a concurrent call removed it first
            raise NotFoundError(f"webhook {webhook_id} not found")
        atomic.give_back(session, *_counter(owner_of(webhook)))
    session.expunge(webhook)


def redeliver(session: Session, *, webhook_id: int, event_id: str) -> WebhookEvent:
    """Send the event again, now, with a fresh series of attempts: one that failed (every
    attempt used) after its receiver is mended, or one delivered that the receiver lost. It
    keeps its id (receivers deduplicate by it) and its log; at least once, as ever: a delivery
    loop holding it at that moment may send it too.

    Raises:
        NotFoundError: no such webhook, or no such event of it.
    """
    get_webhook(session, webhook_id=webhook_id)
    mine = (WebhookEvent.webhook_id == webhook_id, WebhookEvent.event_id == event_id)
    with writing(session):
        event = session.scalars(select(WebhookEvent).where(*mine)).one_or_none()
        if event is None:
            raise NotFoundError(f"event {event_id} of webhook {webhook_id} not found")
        event.attempts, event.delivered_at, event.next_attempt_at = 0, None, utcnow()
        session.flush()
        session.expunge(event)  # as set here: the delivery loop may send it before it is read
    return event


def counts(session: Session, *, webhook_ids: list[int], max_attempts: int) -> dict[int, Counts]:
    """Each webhook's events by state (``failed``: ``max_attempts`` tried, none delivered)."""
    state = case(
        (WebhookEvent.delivered_at.is_not(None), "delivered"),
        (WebhookEvent.attempts >= max_attempts, "failed"),
        else_="pending",
    )
    rows = session.execute(
        select(WebhookEvent.webhook_id, state, func.count())
        .where(WebhookEvent.webhook_id.in_(webhook_ids))
        .group_by(WebhookEvent.webhook_id, state)
    )
    found: dict[int, dict[str, int]] = {}
    for webhook_id, name, n in rows:
        found.setdefault(webhook_id, {})[name] = n
    return {w: Counts(**found.get(w, {})) for w in webhook_ids}


def event_status(event: WebhookEvent, *, max_attempts: int) -> str:
    """``delivered``, ``failed`` (``max_attempts`` tried) or ``pending``."""
    if event.delivered_at is not None:
        return "delivered"
    return "failed" if event.attempts >= max_attempts else "pending"


def events(session: Session, *, webhook_id: int, limit: int = MAX_LISTED) -> list[WebhookEvent]:
    """The webhook's events, newest first.

    Raises:
        NotFoundError: no such webhook.
    """
    get_webhook(session, webhook_id=webhook_id)
    return list(
        session.scalars(
            select(WebhookEvent)
            .where(WebhookEvent.webhook_id == webhook_id)
            .order_by(WebhookEvent.id.desc())
            .limit(limit)
        )
    )


def attempts(session: Session, *, webhook_id: int, limit: int = MAX_LISTED) -> list[AttemptRow]:
    """Every delivery attempt of the webhook's events, newest first.

    Raises:
        NotFoundError: no such webhook.
    """
    get_webhook(session, webhook_id=webhook_id)
    rows = session.execute(
        select(
            WebhookAttempt.id,
            WebhookEvent.event_id,
            WebhookEvent.type,
            WebhookAttempt.attempted_at,
            WebhookAttempt.status_code,
            WebhookAttempt.error,
            WebhookAttempt.duration_ms,
        )
        .join(WebhookEvent, WebhookEvent.id == WebhookAttempt.event_id)
        .where(WebhookEvent.webhook_id == webhook_id)
        .order_by(WebhookAttempt.id.desc())
        .limit(limit)
    )
    return [AttemptRow(*row) for row in rows]
