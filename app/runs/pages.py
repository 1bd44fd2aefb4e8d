"""Researcher pages of training runs: the list, the launch form and a run's live page. The
comparisons are :mod:`app.runs.compare_pages`.

The pages call the services directly; their scripts (``static/js/run.js``,
``static/js/compare.js``) poll and draw from ``/api/runs``. Cancel and resume are form posts
with the CSRF token.
"""

from __future__ import annotations

import re
from typing import Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import HTMLResponse
from pydantic import TypeAdapter, ValidationError
from sqlalchemy.orm import Session

from app.core.json_types import from_form
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import DbId, SessionDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect, render
from app.labelling import participants
from app.models import Participant, StudyStatus
from app.runs import experiments, run_state
from app.runs import service as runs
from app.runs.experiments import DEFAULT_SEEDS
from app.runs.schemas import ExperimentCreate, RunCreate, RunOut
from app.studies import service as studies
from engine.errors import InputError
from engine.rl.config import ADVICE_MODES, ALGOS
from engine.teachers import TEACHERS

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])

FORM_DEFAULTS = {
    "advice": "teacher:standing",
    "algo": "bipars-em",
    "timesteps": "200000",
    "seed": "0",
    "n_envs": "4",
    "num_steps": "",
    "checkpoint_every": "",
    "advice_mode": "",
    "pool_weighting": "mean",
    "experiment": "on",
    "seeds": str(DEFAULT_SEEDS),
}
_OPTIONAL = ("num_steps", "checkpoint_every", "advice_mode")
#: Advice choices of pooled advice, and the checkboxes that choose the pool (``pool_<id>``).
POOL_ALL, POOL_CHOSEN, POOL_FIELD = "pool:all", "pool:chosen", "pool_"
_POOL_BOX = re.compile(r"pool_\d{1,10}")
_DB_ID = TypeAdapter(DbId)


@router.get("/runs")
def run_list(
    request: Request,
    session: SessionDep,
    study_id: DbId | None = None,
) -> HTMLResponse:
    """Every run (or one study's), newest first, with a link to launch one."""
    study = studies.get_study(session, study_id=study_id) if study_id else None
    return render(
        request,
        "runs.html",
        {
            "study": study,
            "runs": [RunOut.of(r) for r in runs.list_runs(session, study_id=study_id)],
            "studies": [s for s in studies.list_studies(session) if s.status == StudyStatus.READY],
        },
    )


def _finished(session: Session, study_id: int) -> list[Participant]:
    """The study's finished participants."""
    return [
        s.participant
        for s in participants.list_participants(session, study_id=study_id)
        if s.progress.finished
    ]


def _label(person: Participant) -> str:
    """``participant #3 (Ann)``."""
    return f"participant #{person.id}" + (f" ({person.name})" if person.name else "")


def _advice_choices(finished: list[Participant]) -> list[tuple[str, str]]:
    poolable = [p for p in finished if not p.excluded]
    left_out = " (excluded ones left out)" if len(poolable) < len(finished) else ""
    pooled = (
        [
            (POOL_ALL, f"all {len(poolable)} finished participants, pooled{left_out}"),
            (POOL_CHOSEN, "the participants ticked below, pooled"),
        ]
        if len(poolable) > 1
        else []
    )
    return (
        [
            (f"participant:{p.id}", _label(p) + (", excluded" if p.excluded else ""))
            for p in finished
        ]
        + pooled
        + [(f"teacher:{t}", f"simulated teacher: {t}") for t in TEACHERS]
        + [("none", "none (ppo only)")]
    )


def _form_page(
    request: Request,
    session: Session,
    study_id: int,
    values: dict[str, str],
    errors: dict[str, str],
    status_code: int = 200,
    chosen: list[str] | None = None,
) -> HTMLResponse:
    study = studies.get_ready_study(session, study_id=study_id)
    finished = _finished(session, study_id)
    poolable = [(p.id, _label(p)) for p in finished if not p.excluded]  # excluded: never pooled
    return render(
        request,
        "run_new.html",
        {
            "study": study,
            "values": values,
            "errors": errors,
            "algos": ALGOS,
            "advice_modes": ADVICE_MODES,
            "advice_choices": _advice_choices(finished),
            "poolable": poolable if len(poolable) > 1 else [],
            "chosen": chosen or [],
        },
        status_code=status_code,
    )


@router.get("/runs/new")
def new_run_form(
    request: Request,
    session: SessionDep,
    study_id: DbId | None = None,
) -> HTMLResponse:
    """The launch form for a run of ``study_id``; without one, the study picker (a bookmarked
    or typed ``/runs/new``)."""
    if study_id is None:
        return render(
            request,
            "run_pick_study.html",
            {
                "study": None,
                "studies": [
                    s for s in studies.list_studies(session) if s.status == StudyStatus.READY
                ],
            },
        )
    return _form_page(request, session, study_id, dict(FORM_DEFAULTS), {})


def _chosen(fields: dict[str, str]) -> list[str]:
    """The participant ids ticked to pool (checkboxes ``pool_<id>``)."""
    return [k.removeprefix(POOL_FIELD) for k in fields if _POOL_BOX.fullmatch(k)]


def _body(study_id: int, values: dict[str, str], chosen: list[str]) -> dict[str, Any]:
    """The ``POST /api/runs`` body a submitted form stands for."""
    kind, _, who = values["advice"].partition(":")
    body: dict[str, Any] = {"study_id": study_id, "algo": values["algo"]}
    if values["advice"] in (POOL_ALL, POOL_CHOSEN):  # the weighting select weights pools only
        body["pool_weighting"] = values["pool_weighting"] or "mean"
    if values["advice"] == POOL_ALL:
        body["all_participants"] = True
    elif values["advice"] == POOL_CHOSEN:
        body["participant_ids"] = chosen
    elif kind == "participant":
        body["participant_id"] = who
    elif kind == "teacher":
        body["teacher"] = who
    for key in ("timesteps", "seed", "n_envs", *_OPTIONAL):
        if values[key].strip() or key not in _OPTIONAL:
            body[key] = values[key].strip()
    return body


@router.post("/runs", dependencies=[CsrfChecked])
def create_run(request: Request, session: SessionDep, fields: FormFields) -> Response:
    """Validate like ``POST /api/runs``; errors are shown next to the form's fields."""
    values = {k: fields.get(k, "") for k in FORM_DEFAULTS}
    chosen = _chosen(fields)
    try:  # bounded here: the error page looks the study up, and SQLite overflows past int64
        study_id = _DB_ID.validate_python(fields.get("study_id", ""))
    except ValidationError:
        raise InputError("the form names no study") from None
    body = _body(study_id, values, chosen)
    try:
        if values["experiment"]:  # seeds checked even where ppo (its own baseline) ignores them
            spec = from_form(
                ExperimentCreate, body | {"seeds": values["seeds"].strip()}
            ).experiment_spec()
            if values["algo"] != "ppo":
                experiment = experiments.create_experiment(session, spec=spec)
                return redirect(f"/experiments/{experiment.id}")
        run = runs.create_run(session, spec=from_form(RunCreate, body).spec())
    except ValidationError as exc:
        errors = {str(e["loc"][0]) if e["loc"] else "form": e["msg"] for e in exc.errors()}
        return _form_page(request, session, study_id, values, errors, 422, chosen)
    except InputError as exc:
        return _form_page(request, session, study_id, values, {"form": str(exc)}, 422, chosen)
    return redirect(f"/runs/{run.id}")


@router.get("/runs/{run_id}")
def run_page(run_id: DbId, request: Request, session: SessionDep) -> HTMLResponse:
    """Live progress, metrics, the learning curve and z, the checkpoints, cancel/resume."""
    run = runs.get_run(session, run_id=run_id)
    return render(
        request,
        "run.html",
        {
            "run": RunOut.of(run),
            "study": studies.get_study(session, study_id=run.study_id),
            "checkpoints": run_state.checkpoint_steps(session, run_id=run_id),
            "has_advice": run.advice is not None,
        },
    )


@router.post("/runs/{run_id}/cancel", dependencies=[CsrfChecked])
def cancel(run_id: DbId, session: SessionDep) -> Response:
    runs.cancel_run(session, run_id=run_id)
    return redirect(f"/runs/{run_id}")


@router.post("/runs/{run_id}/resume", dependencies=[CsrfChecked])
def resume(run_id: DbId, session: SessionDep) -> Response:
    runs.resume_run(session, run_id=run_id)
    return redirect(f"/runs/{run_id}")
