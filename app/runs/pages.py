"""Researcher pages of training runs: the list, the launch form, a run's live page, and the
comparisons (one run's Human vs Agent Preference Tree; several runs on the same advice).

The pages call the services directly; their scripts (``static/js/run.js``,
``static/js/compare.js``) poll and draw from ``/api/runs``. Cancel and resume are form posts
with the CSRF token.
"""

from __future__ import annotations

import re
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response
from fastapi.responses import HTMLResponse
from pydantic import TypeAdapter, ValidationError
from sqlalchemy.orm import Session

from app.core.errors import PendingError
from app.core.json_types import FORM_INPUT
from app.http.csrf import CsrfChecked, FormFields
from app.http.deps import MAX_DB_ID, DbId, SessionDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, redirect, render, thumb_template
from app.jobs.settings import run_dir
from app.models import Run
from app.runs import comparison, experiment_notes, experiments
from app.runs import report as run_report
from app.runs import service as runs
from app.runs.api import RunsRootDep
from app.runs.experiments import DEFAULT_SEEDS
from app.runs.experiments_api import ExperimentCreate
from app.runs.schemas import Judge, RunCreate, RunOut
from app.studies import participants
from app.studies import service as studies
from engine.errors import InputError
from engine.judges import DEFAULT_JUDGE, judge_name
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
    "experiment": "on",
    "seeds": str(DEFAULT_SEEDS),
}
_OPTIONAL = ("num_steps", "checkpoint_every", "advice_mode")
#: Advice choices of pooled advice, and the checkboxes that choose the pool (``pool_<id>``).
POOL_ALL, POOL_CHOSEN, POOL_FIELD = "pool:all", "pool:chosen", "pool_"
_POOL_BOX = re.compile(r"pool_\d{1,10}")
_DB_ID = TypeAdapter(DbId)
JUDGE_LABELS = (
    ("return", "the return it earns from each state (provisional)"),
    (
        "behaviour",
        "its behaviour: a revealed-preference tree of the postures it actually adopts "
        "(provisional)",
    ),
    ("shaped", "diagnostic, is your advice still in its reward? R + z F"),
    ("shaping", "diagnostic, is your advice still in its reward? the advice part z F"),
    ("shaped-value", "diagnostic, is your advice still in its reward? its shaped critic V"),
)


@router.get("/runs")
def run_list(
    request: Request,
    session: SessionDep,
    study_id: Annotated[int | None, Query(ge=1, le=MAX_DB_ID)] = None,
) -> HTMLResponse:
    """Every run (or one study's), newest first, with a link to launch one."""
    study = studies.get_study(session, study_id=study_id) if study_id else None
    return render(
        request,
        "runs.html",
        {
            "study": study,
            "runs": [RunOut.of(r) for r in runs.list_runs(session, study_id=study_id)],
            "studies": [s for s in studies.list_studies(session) if s.status == "ready"],
        },
    )


def _finished(session: Session, study_id: int) -> list[tuple[int, str]]:
    """(id, label) of the study's finished participants."""
    return [
        (p.id, f"participant #{p.id}" + (f" ({p.name})" if p.name else ""))
        for p in (
            s.participant
            for s in participants.list_participants(session, study_id=study_id)
            if s.progress.finished
        )
    ]


def _advice_choices(finished: list[tuple[int, str]]) -> list[tuple[str, str]]:
    pooled = (
        [
            (POOL_ALL, f"all {len(finished)} finished participants, pooled"),
            (POOL_CHOSEN, "the participants ticked below, pooled"),
        ]
        if len(finished) > 1
        else []
    )
    return (
        [(f"participant:{pid}", label) for pid, label in finished]
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
            "poolable": finished if len(finished) > 1 else [],
            "chosen": chosen or [],
        },
        status_code=status_code,
    )


@router.get("/runs/new")
def new_run_form(
    request: Request,
    session: SessionDep,
    study_id: Annotated[int | None, Query(ge=1, le=MAX_DB_ID)] = None,
) -> HTMLResponse:
    """The launch form for a run of ``study_id``; without one, the study picker (a bookmarked
    or typed ``/runs/new``)."""
    if study_id is None:
        return render(
            request,
            "run_pick_study.html",
            {
                "study": None,
                "studies": [s for s in studies.list_studies(session) if s.status == "ready"],
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
            spec = ExperimentCreate.model_validate(
                body | {"seeds": values["seeds"].strip()}, context=FORM_INPUT
            ).spec()
            if values["algo"] != "ppo":
                experiment = experiments.create_experiment(session, spec=spec)
                return redirect(f"/experiments/{experiment.id}")
        run = runs.create_run(
            session, **RunCreate.model_validate(body, context=FORM_INPUT).model_dump()
        )
    except ValidationError as exc:
        errors = {str(e["loc"][0]) if e["loc"] else "form": e["msg"] for e in exc.errors()}
        return _form_page(request, session, study_id, values, errors, 422, chosen)
    except InputError as exc:
        return _form_page(request, session, study_id, values, {"form": str(exc)}, 422, chosen)
    return redirect(f"/runs/{run.id}")


@router.get("/runs/{run_id}")
def run_page(
    run_id: DbId, request: Request, session: SessionDep, root: RunsRootDep
) -> HTMLResponse:
    """Live progress, metrics, the learning curve and z, the checkpoints, cancel/resume."""
    run = runs.get_run(session, run_id=run_id)
    return render(
        request,
        "run.html",
        {
            "run": RunOut.of(run),
            "study": studies.get_study(session, study_id=run.study_id),
            "checkpoints": comparison.checkpoints(run_dir(root, run_id)),
            "has_advice": run.advice is not None,
        },
    )


@router.post("/runs/{run_id}/cancel", dependencies=[CsrfChecked])
def cancel(run_id: DbId, session: SessionDep) -> Response:
    runs.cancel_run(session, run_id=run_id)
    return redirect(f"/runs/{run_id}")


@router.post("/runs/{run_id}/resume", dependencies=[CsrfChecked])
def resume(run_id: DbId, session: SessionDep, root: RunsRootDep) -> Response:
    runs.resume_run(session, run_id=run_id, runs_dir=root)
    return redirect(f"/runs/{run_id}")


@router.get("/runs/{run_id}/compare")
def compare_page(
    run_id: DbId,
    request: Request,
    session: SessionDep,
    root: RunsRootDep,
    checkpoint: Annotated[int | None, Query(ge=0)] = None,
    judge: Judge | None = None,
) -> HTMLResponse:
    """Human and Agent Preference Tree side by side, the rejected advice, the metrics with a
    verdict, a checkpoint selector and the conformance curve."""
    run = runs.get_run(session, run_id=run_id)
    runs.advice_of(run)  # 409 page for a run without advice
    steps = comparison.checkpoints(run_dir(root, run_id))
    selected = checkpoint if checkpoint in steps else (steps[-1] if steps else None)
    shown = judge or comparison.shown_judge(session, run_id=run_id, step=selected)
    return render(
        request,
        "compare.html",
        {
            "run": RunOut.of(run),
            "study": studies.get_study(session, study_id=run.study_id),
            "checkpoints": steps,
            "who": run_report.who(run),
            "whose": run_report.whose(run),
            "selected": selected,
            "experiment_notes": experiment_notes.notes_of_runs(
                session, run_ids=[run_id], judge=judge_name(shown)
            ),
            "thumb_template": thumb_template(run.study_id),
            "image_template": thumb_template(run.study_id).removesuffix("?size=thumb"),
            "others": len(runs.same_advice_runs(session, run=run)),
            "judge": judge_name(shown),
            "judges": JUDGE_LABELS,
        },
    )


@router.get("/runs/{run_id}/compare-runs")
def compare_runs_page(
    run_id: DbId, request: Request, session: SessionDep, root: RunsRootDep
) -> HTMLResponse:
    """Every run on the same advice as ``run_id`` (e.g. ``ppo`` vs ``bipars-em``): metrics at
    each one's latest checkpoint, side by side, and their conformance curves."""
    run = runs.get_run(session, run_id=run_id)
    runs.advice_of(run)
    rows = [_latest(session, r, root) for r in runs.same_advice_runs(session, run=run)]
    return render(
        request,
        "compare_runs.html",
        {
            "run": RunOut.of(run),
            "study": studies.get_study(session, study_id=run.study_id),
            "rows": rows,
            "experiment_notes": experiment_notes.notes_of_runs(
                session, run_ids=[r["run"].id for r in rows], judge=DEFAULT_JUDGE
            ),
            "whose": run_report.whose(run),
            "advice": runs.advice_label(run),
        },
    )


def _latest(session: Session, run: Run, root: Any) -> dict[str, Any]:
    """A run with its metrics at its latest judged checkpoint (None before the first one)."""
    try:
        curve = comparison.conformance_curve(
            session, run_id=run.id, out=run_dir(root, run.id), judge="shaped"
        )
    except (PendingError, InputError):  # not judged yet, or never by this judge: no metrics
        curve = []
    steps = [step for step, _ in curve]
    metrics = curve[-1][1] if curve else None
    last = run.metrics or {}
    return {
        "run": RunOut.of(run),
        "step": steps[-1] if steps else None,
        "metrics": metrics,
        "return_100": last.get("return_100"),
        "z_mean": last.get("z_mean"),
    }
