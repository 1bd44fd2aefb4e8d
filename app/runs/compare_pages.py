"""Researcher pages that compare: one run's Human and Agent Preference Tree side by side
(``/runs/{id}/compare``), and every run on the same advice (``/runs/{id}/compare-runs``).

Their script (``static/js/compare.js``) polls and draws from ``/api/runs``.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse
from sqlalchemy.orm import Session

from app.core.errors import PendingError
from app.evaluations import results as evaluations_results
from app.http.deps import DbId, SessionDep, StepParam
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, render, thumb_template
from app.models import Run
from app.runs import comparison, experiment_notes, report, run_state
from app.runs import service as runs
from app.runs.imported import is_imported
from app.runs.imported_schemas import NOT_SEEN
from app.runs.schemas import Judge, RunOut
from app.studies import service as studies
from engine.errors import InputError
from engine.judges import DEFAULT_JUDGE, VERDICT_JUDGES, judge_name

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])
JUDGE_LABELS = (
    ("return", "the return it earns from each state (failed validation)"),
    (
        "behaviour",
        "its behaviour: a revealed-preference tree of the postures it actually adopts "
        "(failed validation)",
    ),
    ("shaped", "diagnostic, is your advice still in its reward? R + z F"),
    ("shaping", "diagnostic, is your advice still in its reward? the advice part z F"),
    ("shaped-value", "diagnostic, is your advice still in its reward? its shaped critic V"),
)


@router.get("/runs/{run_id}/compare")
def compare_page(
    run_id: DbId,
    request: Request,
    session: SessionDep,
    checkpoint: StepParam | None = None,
    judge: Judge | None = None,
) -> HTMLResponse:
    """Human and Agent Preference Tree side by side, the rejected advice, the metrics with a
    verdict, a checkpoint selector and the conformance curve."""
    run = runs.get_run(session, run_id=run_id)
    runs.advice_of(run)  # 409 page for a run without advice
    steps = run_state.checkpoint_steps(session, run_id=run_id)
    selected = checkpoint if checkpoint in steps else (steps[-1] if steps else None)
    shown = judge or comparison.shown_judge(session, run_id=run_id, step=selected)
    imported = is_imported(run)
    if imported and judge_name(shown) not in VERDICT_JUDGES:  # it has no reward or critic
        shown = DEFAULT_JUDGE
    return render(
        request,
        "compare.html",
        {
            **_run_context(session, run, [run_id], judge_name(shown)),
            "checkpoints": steps,
            "who": report.who(run),
            "selected": selected,
            "thumb_template": thumb_template(run.study_id),
            "image_template": thumb_template(run.study_id).removesuffix("?size=thumb"),
            "others": len(runs.same_advice_runs(session, run=run)),
            "judge": judge_name(shown),
            "judges": [j for j in JUDGE_LABELS if not imported or j[0] in VERDICT_JUDGES],
            "not_seen": NOT_SEEN,
        },
    )


@router.get("/runs/{run_id}/compare-runs")
def compare_runs_page(run_id: DbId, request: Request, session: SessionDep) -> HTMLResponse:
    """Every run on the same advice as ``run_id`` (e.g. ``ppo`` vs ``bipars-em``): metrics at
    each one's latest checkpoint, side by side, and their conformance curves."""
    run = runs.get_run(session, run_id=run_id)
    runs.advice_of(run)
    rows = [_latest(session, r) for r in runs.same_advice_runs(session, run=run)]
    return render(
        request,
        "compare_runs.html",
        {
            **_run_context(session, run, [r["run"].id for r in rows], DEFAULT_JUDGE),
            "rows": rows,
            "advice": runs.advice_label(run),
        },
    )


def _run_context(session: Session, run: Run, shown: list[int], judge: str) -> dict[str, Any]:
    """What both pages show of ``run``: it, its study, whose advice, the experiment verdicts
    on the runs ``shown`` by ``judge``, and beside them the experiments' agent evaluations."""
    notes = experiment_notes.notes_of_runs(session, run_ids=shown, judge=judge)
    return {
        "run": RunOut.of(run),
        "study": studies.get_study(session, study_id=run.study_id),
        "whose": report.whose(run),
        "experiment_notes": notes,
        **evaluations_results.notes_of_experiments(session, [n.experiment_id for n in notes]),
    }


def _latest(session: Session, run: Run) -> dict[str, Any]:
    """A run with its metrics at its latest judged checkpoint (None before the first one; an
    imported policy's never: it has no ``shaped`` judge, which this table shows)."""
    try:
        curve = comparison.conformance_curve(session, run_id=run.id, judge="shaped")
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
