"""Researcher pages: the study list, the create-study form, a study's page, invitations.

The pages call the same services as the REST API; the study page draws the trees in the
browser (``static/js/study.js``) from ``GET /api/studies/{id}/trees``.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import HTMLResponse
from pydantic import ValidationError
from sqlalchemy.orm import Session

from app.core.json_types import IntParam, from_form
from app.core.limits import MAX_BATCH
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, RuntimeDep, SessionDep, SettingsDep
from app.http.forms import REFUSED, invite_count, refused
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect, render, thumb_template
from app.http.urls import image_url
from app.labelling import dashboard, participants, quality
from app.models import StudyStatus
from app.recruiting.pages import form_echo
from app.runs import power as runs_power
from app.runs.experiments import DEFAULT_SEEDS
from app.settings import Settings
from app.studies import service as studies
from app.studies.clips import CLIPS_WARNING, clips_state
from app.studies.crowd_pages import crowd_context, crowd_options
from app.studies.schemas import StudyCreate
from app.webhooks.outbox import Owner
from app.webhooks.section import webhooks_context
from engine.candidates import MAX_CANDIDATES, SAMPLING_MODES
from engine.disagreement import MAX_PAIRS
from engine.envs import DEFAULT_ENV_ID
from engine.errors import InputError
from engine.practice import MAX_PRACTICE_PAIRS, MIN_PRACTICE_PAIRS

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])

#: Suggestions for the env field; any Gymnasium MuJoCo id is accepted.
SUGGESTED_ENVS = (
    "Humanoid-v5",
    "HumanoidStandup-v5",
    "Walker2d-v5",
    "Hopper-v5",
    "HalfCheetah-v5",
    "Ant-v5",
    "Swimmer-v5",
)
DEFAULT_INSTRUCTIONS = (
    "You will see two pictures of a simulated robot at a time. Pick the one you would rather "
    "the robot be in: click it, or press the left or right arrow key. Winners meet again in "
    "later rounds until one is left."
)
FORM_DEFAULTS = {
    "name": "",
    "env_id": DEFAULT_ENV_ID,
    "n_candidates": "16",
    "p": "0.9",
    "seed": "0",
    "sampling": "uniform",
    "disagreement_pairs": "0",
    "practice_pairs": "0",
    "allow_ties": "",
    "clips": "",
    "instructions": DEFAULT_INSTRUCTIONS,
}


#: Fields a posted form may leave out (a form from before they existed, a checkbox not
#: ticked): their defaults.
OPTIONAL_FIELDS = {
    "disagreement_pairs": "0",
    "practice_pairs": "0",
    "allow_ties": "",
    "clips": "",
}


@router.get("/studies")
def study_list(request: Request, session: SessionDep) -> HTMLResponse:
    """Every study, newest first."""
    return render(request, "studies.html", {"studies": studies.list_studies(session)})


def _form_page(
    request: Request, values: dict[str, str], errors: dict[str, str], status_code: int = 200
) -> HTMLResponse:
    return render(
        request,
        "study_new.html",
        {
            "values": values,
            "errors": errors,
            "envs": SUGGESTED_ENVS,
            "sampling_modes": SAMPLING_MODES,
            "max_candidates": MAX_CANDIDATES,
            "max_pairs": MAX_PAIRS,
            "practice_range": (MIN_PRACTICE_PAIRS, MAX_PRACTICE_PAIRS),
            "clips_warning": CLIPS_WARNING,
        },
        status_code=status_code,
    )


@router.get("/studies/new")
def new_study_form(request: Request) -> HTMLResponse:
    return _form_page(request, dict(FORM_DEFAULTS), {})


@router.post("/studies", dependencies=[CsrfChecked])
def create_study(
    request: Request, session: SessionDep, runtime: RuntimeDep, fields: FormFields
) -> Response:
    """Validate like ``POST /api/studies``; errors are shown next to the form's fields."""
    values = {k: fields.get(k, OPTIONAL_FIELDS.get(k, "")) for k in FORM_DEFAULTS}
    try:
        body = from_form(StudyCreate, _form_body(values))
        study = studies.create_study(session, spec=body.spec())
    except ValidationError as exc:
        errors = {str(e["loc"][0]) if e["loc"] else "form": e["msg"] for e in exc.errors()}
        return _form_page(request, values, errors, status_code=422)
    except InputError as exc:
        return _form_page(request, values, {"form": str(exc)}, status_code=422)
    runtime.prepare_later(study.id)
    return redirect(f"/studies/{study.id}")


def _form_body(values: dict[str, str]) -> dict[str, Any]:
    """The form's text fields as ``StudyCreate`` reads them: trimmed (the instructions as
    typed), and the checkboxes as booleans (a browser sends one only when ticked)."""
    body: dict[str, Any] = {k: v if k == "instructions" else v.strip() for k, v in values.items()}
    body["allow_ties"], body["clips"] = bool(body["allow_ties"]), bool(body["clips"])
    return body


@router.get("/studies/{study_id}")
def study_page(
    study_id: DbId,
    request: Request,
    session: SessionDep,
    settings: SettingsDep,
    invited: Annotated[int, IntParam(ge=0, le=MAX_BATCH)] = 0,
) -> HTMLResponse:
    """Candidates, participants with progress and invite links, finished trees, and
    webhooks."""
    return render_study_page(request, session, settings, study_id, {"invited": invited})


@router.post("/studies/{study_id}/crowd", dependencies=[CsrfChecked])
def set_crowd(
    study_id: DbId, request: Request, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    """Save the open-link form, then show the study page's crowd section; a bad field shows
    the page again (422) with the form as it was sent and what is wrong."""
    try:
        quality.configure_crowd(session, study_id=study_id, options=crowd_options(fields))
    except InputError as exc:
        again = {"crowd_form": form_echo(fields), "crowd_error": str(exc)}
        return render_study_page(request, session, settings, study_id, again, status_code=422)
    return redirect(f"/studies/{study_id}#crowd")


def render_study_page(
    request: Request,
    session: Session,
    settings: Settings,
    study_id: int,
    extra: dict[str, Any],
    status_code: int = 200,
) -> HTMLResponse:
    """The study's page, with ``extra`` in its context."""
    study = studies.get_study(session, study_id=study_id)
    return render(
        request,
        "study.html",
        {
            "study": study,
            "clips_state": clips_state(study),
            "invited": 0,
            "max_batch": MAX_BATCH,
            "thumb_template": thumb_template(study_id),
            "candidates": _candidates(session, study_id),
            "participants": _participants(request, session, study_id),
            **(
                crowd_context(request, session, study_id)
                if study.status == StudyStatus.READY
                else {}
            ),
            **(_power(session, study_id) if study.status == StudyStatus.READY else {}),
            **(_live(session, study_id) if study.status == StudyStatus.READY else {}),
            **webhooks_context(session, Owner("study", study_id), settings),
            **extra,
        },
        status_code=status_code,
    )


def _live(session: Session, study_id: int) -> dict[str, Any]:
    """The live dashboard's first state (``_study_dashboard.html``); the page's script then
    keeps it current from ``GET /api/studies/{id}/dashboard``."""
    return {"live": dashboard.dashboard(session, study_id=study_id)}


def _power(session: Session, study_id: int) -> dict[str, Any]:
    return {
        "power": runs_power.study_power(session, study_id=study_id),
        "enough": runs_power.ENOUGH_MATCHES,
        "seeds": DEFAULT_SEEDS,
    }


def _candidates(session: Session, study_id: int) -> list[dict[str, Any]]:
    return [
        {
            "id": c.id,
            "env_reward": c.env_reward,
            "thumb_url": image_url(study_id, c.id, "thumb"),
            "image_url": image_url(study_id, c.id),
        }
        for c in studies.list_candidates(session, study_id=study_id)
    ]


def _participants(request: Request, session: Session, study_id: int) -> list[dict[str, Any]]:
    base = str(request.base_url)
    return [
        {
            "id": s.participant.id,
            "name": s.participant.name,
            "done": s.progress.done,
            "total": s.progress.total,
            "finished": s.progress.finished,
            "started": s.progress.done > 0,
            "finished_at": s.participant.finished_at,
            "excluded": s.participant.excluded,
            "invite_url": participants.invite_url(base, s.participant.token),
        }
        for s in participants.list_participants(session, study_id=study_id)
    ]


@router.post("/studies/{study_id}/participants", dependencies=[CsrfChecked])
def invite(
    study_id: DbId, request: Request, session: SessionDep, settings: SettingsDep, fields: FormFields
) -> Response:
    """Invite one or many participants, then show the study page with their links; a bad
    count shows the page again with the form as typed."""
    name = fields.get("name", "").strip()[:200] or None
    try:
        count = invite_count(fields, "participants")
        people = participants.add_participants(session, study_id=study_id, count=count, name=name)
    except REFUSED as exc:
        again, status = refused("invite", fields, exc)
        return render_study_page(request, session, settings, study_id, again, status)
    return redirect(f"/studies/{study_id}?invited={len(people)}#participants")
