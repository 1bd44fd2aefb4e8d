"""The "Webhooks" section of the study and survey pages (``templates/_webhooks.html``):
what it shows, each webhook with its latest delivery attempts. Its forms post to
:mod:`app.webhooks.pages`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from app.models import Webhook
from app.settings import Settings
from app.webhooks import service
from app.webhooks.outbox import EVENT_TYPES, Owner

#: Attempts shown per webhook on the page (the API lists more).
SHOWN_ATTEMPTS = 10
#: The events a study's or a survey's webhooks get, by the first word of their type.
_NOUNS = {"study": ("participant", "study"), "survey": ("respondent", "survey")}


@dataclass(frozen=True)
class WebhookView:
    """A webhook as the section shows it."""

    webhook: Webhook
    counts: service.Counts
    attempts: list[service.AttemptRow]


def webhooks_context(session: Session, owner: Owner, settings: Settings) -> dict[str, Any]:
    """What the section needs: the owner's webhooks with their latest attempts."""
    hooks = service.list_webhooks(session, owner=owner)
    counts = service.counts(
        session, webhook_ids=[h.id for h in hooks], max_attempts=settings.webhook_max_attempts
    )
    views = [
        WebhookView(
            h,
            counts[h.id],
            service.attempts(session, webhook_id=h.id, limit=SHOWN_ATTEMPTS),
        )
        for h in hooks
    ]
    return {
        "webhooks": views,
        "webhook_path": f"{page_of(owner)}/webhooks",
        "webhook_events": [t for t in EVENT_TYPES if t.split(".")[0] in _NOUNS[owner.noun]],
    }


def page_of(owner: Owner) -> str:
    """The page the owner's section is on: ``/studies/3``, ``/surveys/2``."""
    return f"/{'studies' if owner.noun == 'study' else 'surveys'}/{owner.id}"
