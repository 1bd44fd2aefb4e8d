"""``/api/runs/{id}/...`` at a checkpoint: the Agent Preference Tree, conformance, the
compare page's report, curves, CSV, tree images and the self-contained HTML report.

``checkpoint`` query parameters default to the latest checkpoint; ``judge`` picks how the
agent scores states: ``return`` what its policy earns from each state and ``behaviour`` how
near its own rollouts come to each state (a revealed-preference tree), neither of which passed
the validation on known answers (docs/validation.md); the diagnostics ``shaped`` R + z F,
``shaping`` z F and ``shaped-value`` the shaped critic (``value``, its old name, is still
accepted). What is shown of a checkpoint is read from its artefact, which the run's executor
stores; until then these endpoints answer 202 ``{"status": "pending"}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Query, Response
from fastapi.responses import HTMLResponse
from sqlalchemy.orm import Session

from app.core.figures import FORMATS
from app.evaluations import results as evaluations_results
from app.http.deps import DbId, ResearcherDep, SessionDep, SettingsDep, StepParam
from app.http.errors import RESPONSES
from app.http.files import attachment
from app.models import Run
from app.runs import comparison, experiments
from app.runs import report as runs_report
from app.runs import service as runs
from app.runs.compare_schemas import CheckpointReportOut, ConformanceOut, CurvePointOut, TreeJson
from app.runs.schemas import Judge
from app.studies import service as studies
from engine.judges import DEFAULT_JUDGE
from engine.treefile import tree_to_json

router = APIRouter(prefix="/runs", tags=["runs"])
Step = Annotated[StepParam | None, Query(description="Checkpoint timesteps (default: latest).")]
JudgeQuery = Annotated[Judge, Query(description="How the agent scores states.")]
#: The answers of an operation on a run's checkpoint, besides those of every operation.
NO_CHECKPOINT: dict[int | str, dict[str, Any]] = {
    409: {
        **RESPONSES[409],
        "description": "The run has no checkpoint yet, or no advice to compare with.",
    }
}
#: The answer while a checkpoint's artefact is being computed by the run's executor.
PENDING: dict[int | str, dict[str, Any]] = {
    202: {"description": 'Not computed yet: {"status": "pending"}; ask again.'},
    **NO_CHECKPOINT,
}
#: The report inlines its styles and images and runs nothing; nobody may frame it.
REPORT_CSP = (
    "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; "
    "form-action 'none'; frame-ancestors 'none'"
)


@dataclass(frozen=True)
class AtCheckpoint:
    """A researcher's question about run ``run_id`` at ``checkpoint`` (None: the latest), as
    ``judge`` reads the agent."""

    session: Session
    run_id: int
    checkpoint: int | None
    judge: str

    def view(self) -> tuple[Run, comparison.CheckpointView]:
        return load_view(self.session, self.run_id, self.checkpoint)


def at_checkpoint(
    run_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> AtCheckpoint:
    return AtCheckpoint(session, run_id, checkpoint, judge)


AtCheckpointDep = Annotated[AtCheckpoint, Depends(at_checkpoint)]


def load_view(
    session: Session, run_id: int, checkpoint: int | None
) -> tuple[Run, comparison.CheckpointView]:
    """The run and the stored artefact of its checkpoint (PendingError: 202)."""
    run = runs.get_run(session, run_id=run_id)
    runs.advice_of(run)
    step = comparison.pick_checkpoint(session, run_id=run_id, step=checkpoint)
    return run, comparison.checkpoint_view(session, run_id=run_id, step=step)


@router.get("/{run_id}/agent-tree", responses=PENDING)
def agent_tree(at: AtCheckpointDep) -> TreeJson:
    """The Agent Preference Tree at a checkpoint: the advice bracket replayed with the agent
    as the judge (``acv.tree/1``); 202 while the checkpoint is being judged."""
    return tree_to_json(at.view()[1].tree(at.judge))


@router.get("/{run_id}/conformance", responses=PENDING)
def conformance(at: AtCheckpointDep) -> ConformanceOut:
    """The conformance metrics at a checkpoint, exactly as ``acv compare --json`` prints."""
    return ConformanceOut.of(at.view()[1].of(at.judge))


@router.get("/{run_id}/checkpoint-report", responses=PENDING)
def checkpoint_report(at: AtCheckpointDep) -> CheckpointReportOut:
    """What the compare page shows of a checkpoint: the verdict, the states to highlight,
    every judge's agreement side by side, and the per-candidate table."""
    run, view = at.view()
    return CheckpointReportOut.of(view, at.judge, runs_report.whose(run))


@router.get("/{run_id}/conformance-curve", responses=PENDING)
def conformance_curve(
    run_id: DbId, session: SessionDep, _: ResearcherDep, judge: JudgeQuery = DEFAULT_JUDGE
) -> list[CurvePointOut]:
    """The conformance metrics at every judged checkpoint (``{"checkpoint": step, ...}``)."""
    runs.advice_of(runs.get_run(session, run_id=run_id))
    return [
        CurvePointOut.at(step, m)
        for step, m in comparison.conformance_curve(session, run_id=run_id, judge=judge)
    ]


@router.get(
    "/{run_id}/conformance.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}, **PENDING},
)
def conformance_csv(at: AtCheckpointDep) -> Response:
    """The metrics as CSV: one row per judged checkpoint, or only ``checkpoint``'s."""
    if at.checkpoint is None:
        runs.advice_of(runs.get_run(at.session, run_id=at.run_id))  # 409 without advice
        rows = comparison.conformance_curve(at.session, run_id=at.run_id, judge=at.judge)
    else:
        view = at.view()[1]
        rows = [(view.step, view.of(at.judge))]
    which = "curve" if at.checkpoint is None else f"step{rows[0][0]}"
    name = f"run-{at.run_id}-conformance-{which}-{at.judge}.csv"
    return attachment(comparison.csv_text(rows).encode(), "text/csv", name)


@router.get(
    "/{run_id}/trees/{which}.{fmt}",
    response_class=Response,
    responses={200: {"content": {m: {} for m in FORMATS.values()}}, **PENDING},
)
def tree_image(
    which: Literal["human", "agent"],
    fmt: Literal["svg", "png"],
    at: AtCheckpointDep,
    settings: SettingsDep,
) -> Response:
    """A tree as SVG or PNG with thumbnails; the rejected advice is drawn in red."""
    run, view = at.view()
    thumbs = runs_report.thumb_paths(at.session, data_dir=settings.data_dir, study_id=run.study_id)
    data = runs_report.tree_image(run, view, at.judge, which, thumbs, fmt)
    return attachment(data, FORMATS[fmt], f"run-{at.run_id}-{which}-tree-{view.step}.{fmt}")


@router.get("/{run_id}/report.html", response_class=HTMLResponse, responses=PENDING)
def report(at: AtCheckpointDep, settings: SettingsDep, download: bool = False) -> HTMLResponse:
    """A self-contained HTML report (both trees, the rejected advice as image pairs, the
    metrics and curves; images inline, no scripts); 202 while the checkpoint is judged."""
    session, run_id = at.session, at.run_id
    run = runs.get_run(session, run_id=run_id)
    study = studies.get_study(session, study_id=run.study_id)
    thumbs = runs_report.thumb_paths(session, data_dir=settings.data_dir, study_id=run.study_id)
    step = comparison.pick_checkpoint(session, run_id=run_id, step=at.checkpoint)
    shown = evaluations_results.notes_of_experiments(
        session, experiments.experiments_of_run(session, run_id=run_id)
    )
    html = runs_report.report_html(
        run,
        session=session,
        study_name=study.name,
        step=step,
        judge=at.judge,
        thumbs=thumbs,
        evaluations=shown,
    )
    headers = {"Content-Security-Policy": REPORT_CSP}
    if download:
        headers["Content-Disposition"] = f'attachment; filename="run-{run_id}-report.html"'
    return HTMLResponse(html, headers=headers)
