"""``/api/runs``: launch training runs, watch them, and compare the agent with the advice.

A run is queued by ``POST /api/runs`` (202) and executed by a worker (:mod:`app.jobs`).
``checkpoint`` query parameters default to the latest checkpoint; ``judge`` picks how the
agent scores states: ``return`` what its policy earns from each state and ``behaviour`` how
near its own rollouts come to each state (a revealed-preference tree), both provisional; the
diagnostics ``shaped`` R + z F, ``shaping`` z F and ``shaped-value`` the shaped critic
(``value``, its old name, is still accepted). What
is shown of a checkpoint is read from its artefact, which the run's executor stores; until
then these endpoints answer 202 ``{"status": "pending"}``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Query, Request, Response
from fastapi.responses import HTMLResponse

from app.core.figures import FORMATS
from app.http.deps import DbId, ResearcherDep, SessionDep, SettingsDep
from app.http.errors import RESPONSES
from app.jobs.settings import JobSettings, run_dir
from app.models import Run, RunStatus
from app.runs import comparison
from app.runs import report as run_report
from app.runs import service as runs
from app.runs.compare_schemas import (
    CheckpointReportOut,
    ConformanceOut,
    CurvePointOut,
    MetricsRowOut,
    TreeJson,
)
from app.runs.schemas import CheckpointOut, Judge, RunCreate, RunCreated, RunOut
from app.studies import service as studies
from engine.judges import DEFAULT_JUDGE
from engine.treefile import tree_to_json

router = APIRouter(prefix="/runs", tags=["runs"])
Step = Annotated[int | None, Query(ge=0, description="Checkpoint timesteps (default: latest).")]
JudgeQuery = Annotated[Judge, Query(description="How the agent scores states.")]
#: The report inlines its styles and images and runs nothing; nobody may frame it.
#: The answer while a checkpoint's artefact is being computed by the run's executor.
#: The answers of an operation on a run's checkpoint, besides those of every operation.
NO_CHECKPOINT: dict[int | str, dict[str, Any]] = {
    409: {
        **RESPONSES[409],
        "description": "The run has no checkpoint yet, or no advice to compare with.",
    }
}
PENDING: dict[int | str, dict[str, Any]] = {
    202: {"description": 'Not computed yet: {"status": "pending"}; ask again.'},
    **NO_CHECKPOINT,
}
REPORT_CSP = (
    "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; "
    "form-action 'none'; frame-ancestors 'none'"
)


def get_runs_root(request: Request) -> Path:
    """Where run directories live (``ACV_RUNS_DIR``, default ``ACV_DATA_DIR/runs``)."""
    jobs = getattr(request.app.state, "job_settings", None) or JobSettings()
    return jobs.runs_root(request.app.state.runtime.settings)


RunsRootDep = Annotated[Path, Depends(get_runs_root)]


def _load(session: SessionDep, run_id: int, root: Path) -> tuple[Run, Path]:
    """The run and its directory; the session's connection goes back to the pool, since
    what follows (agent trees, figures) may take a while."""
    run = runs.get_run(session, run_id=run_id)
    session.rollback()
    return run, run_dir(root, run_id)


@router.post("", status_code=202)
def create_run(body: RunCreate, session: SessionDep, _: ResearcherDep) -> RunCreated:
    """Queue a training run; a worker starts it (``status`` goes ``queued`` -> ``running`` ->
    ``succeeded``, ``failed``, ``cancelled`` or ``interrupted``)."""
    run = runs.create_run(session, **body.model_dump())
    return RunCreated(id=run.id, status=RunStatus(run.status))


@router.get("")
def list_runs(
    session: SessionDep,
    _: ResearcherDep,
    study_id: Annotated[int | None, Query(ge=1, le=2**31 - 1)] = None,
) -> list[RunOut]:
    """All runs, or one study's, newest first."""
    return [RunOut.of(r) for r in runs.list_runs(session, study_id=study_id)]


@router.get("/{run_id}")
def get_run(run_id: DbId, session: SessionDep, _: ResearcherDep) -> RunOut:
    """Status, progress (timesteps done / total), the latest metrics row, the error."""
    return RunOut.of(runs.get_run(session, run_id=run_id))


@router.post("/{run_id}/cancel", status_code=202)
def cancel_run(run_id: DbId, session: SessionDep, _: ResearcherDep) -> RunOut:
    """Cancel a queued run, or stop a running one after its current update (it writes a
    checkpoint first); 409 when it has ended."""
    return RunOut.of(runs.cancel_run(session, run_id=run_id))


@router.post("/{run_id}/resume", status_code=202)
def resume_run(run_id: DbId, session: SessionDep, root: RunsRootDep, _: ResearcherDep) -> RunOut:
    """Queue an interrupted, failed or cancelled run again; it continues from its latest
    checkpoint exactly as if it had never stopped."""
    return RunOut.of(runs.resume_run(session, run_id=run_id, runs_dir=root))


@router.get("/{run_id}/metrics")
def run_metrics(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    after: Annotated[int, Query(ge=-1)] = -1,
) -> list[MetricsRowOut]:
    """The run's metrics rows (one per update) with ``timesteps`` above ``after``."""
    out = _load(session, run_id, root)[1]
    return [MetricsRowOut.model_validate(row) for row in comparison.metrics_rows(out, after)]


@router.get("/{run_id}/checkpoints")
def run_checkpoints(
    run_id: DbId, session: SessionDep, root: RunsRootDep, _: ResearcherDep
) -> list[CheckpointOut]:
    """The run's checkpoints, oldest first."""
    out = _load(session, run_id, root)[1]
    rows = {r["timesteps"]: r for r in comparison.metrics_rows(out)}
    return [CheckpointOut(checkpoint=s, metrics=rows.get(s)) for s in comparison.checkpoints(out)]


@router.get("/{run_id}/advice-tree")
def advice_tree(run_id: DbId, session: SessionDep, _: ResearcherDep) -> TreeJson:
    """The advice the run trains with (its Human Preference Tree), ``acv.tree/1``."""
    return tree_to_json(runs.advice_of(runs.get_run(session, run_id=run_id)))


def load_view(
    session: SessionDep, run_id: int, root: Path, checkpoint: int | None
) -> tuple[Run, comparison.CheckpointView]:
    """The run and the stored artefact of its checkpoint (PendingError: 202)."""
    run, out = _load(session, run_id, root)
    runs.advice_of(run)
    step = comparison.pick_checkpoint(out, checkpoint)
    return run, comparison.checkpoint_view(session, run_id=run_id, step=step)


@router.get("/{run_id}/agent-tree", responses=PENDING)
def agent_tree(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> TreeJson:
    """The Agent Preference Tree at a checkpoint: the advice bracket replayed with the agent
    as the judge (``acv.tree/1``); 202 while the checkpoint is being judged."""
    view = load_view(session, run_id, root, checkpoint)[1]
    return tree_to_json(view.tree(judge))


@router.get("/{run_id}/conformance", responses=PENDING)
def conformance(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> ConformanceOut:
    """The conformance metrics at a checkpoint, exactly as ``acv compare --json`` prints."""
    view = load_view(session, run_id, root, checkpoint)[1]
    return ConformanceOut.of(view.of(judge))


@router.get("/{run_id}/checkpoint-report", responses=PENDING)
def checkpoint_report(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> CheckpointReportOut:
    """What the compare page shows of a checkpoint: the verdict, the states to highlight,
    every judge's agreement side by side, and the per-candidate table."""
    run, view = load_view(session, run_id, root, checkpoint)
    return CheckpointReportOut.of(view, judge, run_report.whose(run))


@router.get("/{run_id}/conformance-curve", responses=PENDING)
def conformance_curve(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> list[CurvePointOut]:
    """The conformance metrics at every judged checkpoint (``{"checkpoint": step, ...}``)."""
    run, out = _load(session, run_id, root)
    runs.advice_of(run)
    return [
        CurvePointOut.at(step, m)
        for step, m in comparison.conformance_curve(session, run_id=run_id, out=out, judge=judge)
    ]


@router.get(
    "/{run_id}/conformance.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}, **PENDING},
)
def conformance_csv(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> Response:
    """The metrics as CSV: one row per judged checkpoint, or only ``checkpoint``'s."""
    run, out = _load(session, run_id, root)
    runs.advice_of(run)
    if checkpoint is None:
        rows = comparison.conformance_curve(session, run_id=run_id, out=out, judge=judge)
    else:
        view = load_view(session, run_id, root, checkpoint)[1]
        rows = [(view.step, view.of(judge))]
    which = "curve" if checkpoint is None else f"step{rows[0][0]}"
    return _attachment(
        comparison.csv_text(rows).encode(),
        "text/csv",
        f"run-{run_id}-conformance-{which}-{judge}.csv",
    )


@router.get(
    "/{run_id}/trees/{which}.{fmt}",
    response_class=Response,
    responses={200: {"content": {m: {} for m in FORMATS.values()}}, **PENDING},
)
def tree_image(
    run_id: DbId,
    which: Literal["human", "agent"],
    fmt: Literal["svg", "png"],
    session: SessionDep,
    settings: SettingsDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> Response:
    """A tree as SVG or PNG with thumbnails; the rejected advice is drawn in red."""
    run = runs.get_run(session, run_id=run_id)
    thumbs = run_report.thumb_paths(session, data_dir=settings.data_dir, study_id=run.study_id)
    run, view = load_view(session, run_id, root, checkpoint)
    human, agent = runs.advice_of(run), view.tree(judge)
    marked = comparison.highlights(view.of(judge))
    doc, title = (
        (human, f"Human Preference Tree ({runs.advice_label(run)})")
        if which == "human"
        else (agent, f"Agent Preference Tree (step {view.step})")
    )
    data = run_report.tree_file(
        doc, thumbs=thumbs, highlight=marked[which == "agent"], title=title, fmt=fmt
    )
    return _attachment(data, FORMATS[fmt], f"run-{run_id}-{which}-tree-{view.step}.{fmt}")


@router.get("/{run_id}/report.html", response_class=HTMLResponse, responses=NO_CHECKPOINT)
def report(
    run_id: DbId,
    session: SessionDep,
    settings: SettingsDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
    download: bool = False,
) -> HTMLResponse:
    """A self-contained HTML report (both trees, the rejected advice as image pairs, the
    metrics and curves; images inline, no scripts)."""
    run = runs.get_run(session, run_id=run_id)
    study = studies.get_study(session, study_id=run.study_id)
    thumbs = run_report.thumb_paths(session, data_dir=settings.data_dir, study_id=run.study_id)
    run, out = _load(session, run_id, root)
    step = comparison.pick_checkpoint(out, checkpoint)
    html = run_report.report_html(
        run, session=session, study_name=study.name, out=out, step=step, judge=judge, thumbs=thumbs
    )
    headers = {"Content-Security-Policy": REPORT_CSP}
    if download:
        headers["Content-Disposition"] = f'attachment; filename="run-{run_id}-report.html"'
    return HTMLResponse(html, headers=headers)


def _attachment(data: bytes, media_type: str, filename: str) -> Response:
    return Response(
        data,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )
