"""The "Webhooks" section of the study and survey pages (``templates/_webhooks.html``):
plain forms that register and remove a webhook through the same services as
``/api/webhooks``, and each webhook's latest delivery attempts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fastapi import APIRouter, Response
from sqlalchemy.orm import Session

from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep, SettingsDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect
from app.models import Webhook
from app.settings import Settings
from app.webhooks import service
from app.webhooks.outbox import EVENT_TYPES, Owner

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])
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
        "webhook_path": f"{_page(owner)}/webhooks",
        "webhook_events": [t for t in EVENT_TYPES if t.split(".")[0] in _NOUNS[owner.noun]],
    }


def _page(owner: Owner) -> str:
    """The page the owner's section is on: ``/studies/3``, ``/surveys/2``."""
    return f"/{'studies' if owner.noun == 'study' else 'surveys'}/{owner.id}"


def _add(session: Session, settings: Settings, fields: dict[str, str], owner: Owner) -> Response:
    """Register the URL the form gives (checked before anything is sent)."""
    url = fields.get("url", "").strip()
    service.register(session, owner=owner, url=url, targets=settings.webhook_targets)
    return redirect(f"{_page(owner)}#webhooks")


def _remove(session: Session, webhook_id: int, owner: Owner) -> Response:
    """Remove the webhook: nothing more is sent to it."""
    service.remove(session, webhook_id=webhook_id, owner=owner)
    return redirect(f"{_page(owner)}#webhooks")


@router.post("/studies/{study_id}/webhooks", dependencies=[CsrfChecked])
def add_study_webhook(
    study_id: DbId, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    return _add(session, settings, fields, Owner("study", study_id))


@router.post("/surveys/{survey_id}/webhooks", dependencies=[CsrfChecked])
def add_survey_webhook(
    survey_id: DbId, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    return _add(session, settings, fields, Owner("survey", survey_id))


@router.post("/studies/{study_id}/webhooks/{webhook_id}/delete", dependencies=[CsrfChecked])
def remove_study_webhook(study_id: DbId, webhook_id: DbId, session: SessionDep) -> Response:
    return _remove(session, webhook_id, Owner("study", study_id))


@router.post("/surveys/{survey_id}/webhooks/{webhook_id}/delete", dependencies=[CsrfChecked])
def remove_survey_webhook(survey_id: DbId, webhook_id: DbId, session: SessionDep) -> Response:
    return _remove(session, webhook_id, Owner("survey", survey_id))
