"""The forms of the study and survey pages' "Webhooks" section (``templates/_webhooks.html``,
shown by :mod:`app.webhooks.section`): register and remove a webhook through the same
services as ``/api/webhooks``. A refused URL shows the page again with it as typed."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session

from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep, SettingsDep
from app.http.forms import REFUSED, refused
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect
from app.settings import Settings
from app.studies.pages import render_study_page
from app.surveys.pages import render_survey_page
from app.webhooks import service
from app.webhooks.outbox import Owner
from app.webhooks.section import page_of

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])


def _add(
    request: Request, session: Session, settings: Settings, fields: dict[str, str], owner: Owner
) -> Response:
    """Register the URL the form gives (checked before anything is sent)."""
    url = fields.get("url", "").strip()
    try:
        service.register(session, owner=owner, url=url, targets=settings.webhook_targets)
    except REFUSED as exc:
        again, status = refused("webhook", fields, exc)
        show = render_study_page if owner.noun == "study" else render_survey_page
        return show(request, session, settings, owner.id, again, status)
    return redirect(f"{page_of(owner)}#webhooks")


def _remove(session: Session, webhook_id: int, owner: Owner) -> Response:
    """Remove the webhook: nothing more is sent to it."""
    service.remove(session, webhook_id=webhook_id, owner=owner)
    return redirect(f"{page_of(owner)}#webhooks")


@router.post("/studies/{study_id}/webhooks", dependencies=[CsrfChecked])
def add_study_webhook(
    study_id: DbId, request: Request, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    return _add(request, session, settings, fields, Owner("study", study_id))


@router.post("/surveys/{survey_id}/webhooks", dependencies=[CsrfChecked])
def add_survey_webhook(
    survey_id: DbId,
    request: Request,
    session: SessionDep,
    settings: SettingsDep,
    fields: FormFields,
) -> Response:
    return _add(request, session, settings, fields, Owner("survey", survey_id))


@router.post("/studies/{study_id}/webhooks/{webhook_id}/delete", dependencies=[CsrfChecked])
def remove_study_webhook(study_id: DbId, webhook_id: DbId, session: SessionDep) -> Response:
    return _remove(session, webhook_id, Owner("study", study_id))


@router.post("/surveys/{survey_id}/webhooks/{webhook_id}/delete", dependencies=[CsrfChecked])
def remove_survey_webhook(survey_id: DbId, webhook_id: DbId, session: SessionDep) -> Response:
    return _remove(session, webhook_id, Owner("survey", survey_id))
