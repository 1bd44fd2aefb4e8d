"""``/api/webhooks`` (issue 29 §3): register a URL for a study's or a survey's events,
list and remove webhooks, and read each one's events and delivery attempts. Researcher
only."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Response
from sqlalchemy.orm import Session

from app.core.rows import from_row
from app.http.deps import DbId, ResearcherDep, SessionDep, SettingsDep
from app.models import Webhook
from app.webhooks import service
from app.webhooks.outbox import Owner
from app.webhooks.schemas import AttemptOut, EventOut, WebhookIn, WebhookOut
from engine.errors import InputError

router = APIRouter(prefix="/webhooks", tags=["webhooks"])
OwnerId = DbId | None


def webhook_outs(session: Session, hooks: list[Webhook], *, max_attempts: int) -> list[WebhookOut]:
    """The webhooks with their events' counts."""
    counts = service.counts(session, webhook_ids=[h.id for h in hooks], max_attempts=max_attempts)
    return [from_row(WebhookOut, h, **vars(counts[h.id])) for h in hooks]


@router.post(
    "",
    status_code=201,
    responses={
        409: {"description": "The study or survey has the most webhooks it may have."},
        422: {"description": "Not https, a refused address (private, loopback...), or no owner."},
    },
)
def add_webhook(
    body: WebhookIn, session: SessionDep, settings: SettingsDep, _: ResearcherDep
) -> WebhookOut:
    """Register a URL; its secret signs every delivery. The URL is checked before anything
    is sent: https, and every address its host resolves to public."""
    hook = service.register(
        session, owner=body.owner(), url=body.url, targets=settings.webhook_targets
    )
    return webhook_outs(session, [hook], max_attempts=settings.webhook_max_attempts)[0]


@router.get("")
def list_webhooks(
    session: SessionDep,
    settings: SettingsDep,
    _: ResearcherDep,
    study_id: OwnerId = None,
    survey_id: OwnerId = None,
) -> list[WebhookOut]:
    """Webhooks of a study or a survey (or every webhook), oldest first."""
    if study_id is not None and survey_id is not None:
        raise InputError("give at most one of study_id and survey_id")
    owner = None
    if study_id is not None:
        owner = Owner("study", study_id)
    elif survey_id is not None:
        owner = Owner("survey", survey_id)
    hooks = service.list_webhooks(session, owner=owner)
    return webhook_outs(session, hooks, max_attempts=settings.webhook_max_attempts)


@router.get("/{webhook_id}")
def get_webhook(
    webhook_id: DbId, session: SessionDep, settings: SettingsDep, _: ResearcherDep
) -> WebhookOut:
    hook = service.get_webhook(session, webhook_id=webhook_id)
    return webhook_outs(session, [hook], max_attempts=settings.webhook_max_attempts)[0]


@router.delete("/{webhook_id}", status_code=204)
def remove_webhook(webhook_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """Remove a webhook, its undelivered events and its log: nothing more is sent."""
    service.remove(session, webhook_id=webhook_id)
    return Response(status_code=204)


@router.get("/{webhook_id}/events")
def list_events(
    webhook_id: DbId, session: SessionDep, settings: SettingsDep, _: ResearcherDep
) -> list[EventOut]:
    """The webhook's events (its outbox), newest first: at most 500."""
    limit = settings.webhook_max_attempts
    return [
        from_row(EventOut, e, status=service.event_status(e, max_attempts=limit))
        for e in service.events(session, webhook_id=webhook_id)
    ]


@router.post("/{webhook_id}/events/{event_id}/redeliver")
def redeliver_event(
    webhook_id: DbId,
    event_id: Annotated[str, Path(max_length=64)],
    session: SessionDep,
    settings: SettingsDep,
    _: ResearcherDep,
) -> EventOut:
    """Send an event again, now, with a fresh series of attempts (a failed one, once its
    receiver is mended; or a delivered one that it lost). Its id stays the same."""
    event = service.redeliver(session, webhook_id=webhook_id, event_id=event_id)
    limit = settings.webhook_max_attempts
    return from_row(EventOut, event, status=service.event_status(event, max_attempts=limit))


@router.get("/{webhook_id}/attempts")
def list_attempts(webhook_id: DbId, session: SessionDep, _: ResearcherDep) -> list[AttemptOut]:
    """Every delivery attempt of the webhook's events, newest first: at most 500."""
    return [AttemptOut.model_validate(a) for a in service.attempts(session, webhook_id=webhook_id)]
