"""The study page's gold items and exclusions (issue 28 §1): plain forms that call the same
services as ``/api/studies/{id}/gold`` and ``/api/participants/{id}/exclusion``."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.core.errors import NotFoundError
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep, SettingsDep
from app.http.forms import REFUSED, refused
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect
from app.labelling import participants
from app.recruiting.pages import validated
from app.studies import gold
from app.studies.gold_api import GoldItemIn
from app.studies.pages import render_study_page

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])


def _number(text: str) -> int | str:
    """A form's number as an int, or the text as typed (validation then names it)."""
    try:
        return int(text.strip())
    except ValueError:
        return text


@router.post("/studies/{study_id}/gold", dependencies=[CsrfChecked])
def add_gold(
    study_id: DbId, request: Request, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    """Add the gold item the form describes, then show the study page's gold section; a
    refused item shows the page again with the form as typed."""
    numbers = {k: _number(fields.get(k, "")) for k in ("a", "b", "answer")}
    try:
        body = validated(GoldItemIn, {"kind": fields.get("kind", "")} | numbers)
        gold.add_item(
            session, study_id=study_id, kind=body.kind, a=body.a, b=body.b, answer=body.answer
        )
    except REFUSED as exc:
        again, status = refused("gold", fields, exc)
        return render_study_page(request, session, settings, study_id, again, status)
    return redirect(f"/studies/{study_id}#gold")


@router.post("/studies/{study_id}/gold/{item_id}/delete", dependencies=[CsrfChecked])
def delete_gold(study_id: DbId, item_id: DbId, session: SessionDep) -> Response:
    """Remove a gold item nobody answered."""
    gold.delete_item(session, study_id=study_id, item_id=item_id)
    return redirect(f"/studies/{study_id}#gold")


@router.post(
    "/studies/{study_id}/participants/{participant_id}/exclusion", dependencies=[CsrfChecked]
)
def set_exclusion(
    study_id: DbId, participant_id: DbId, session: SessionDep, fields: FormFields
) -> Response:
    """Exclude a participant from pooling and exports, or include them again."""
    person = participants.get_participant(session, participant_id=participant_id)
    if person.study_id != study_id:
        raise NotFoundError(f"participant {participant_id} of study {study_id} not found")
    participants.set_exclusion(
        session, participant_id=participant_id, excluded=fields.get("excluded") == "on"
    )
    return redirect(f"/studies/{study_id}#quality")
