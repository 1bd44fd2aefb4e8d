"""``/api/runs``: launch training runs and watch them (their metrics, checkpoints and
advice). What a checkpoint shows (the agent's tree, conformance, reports) is
:mod:`app.runs.checkpoint_api`.

A run is queued by ``POST /api/runs`` (202) and executed by a worker (:mod:`app.jobs`).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter

from app.core.json_types import IntParam
from app.http.deps import MAX_STEP, DbId, ResearcherDep, SessionDep
from app.models import RunStatus
from app.runs import run_state
from app.runs import service as runs
from app.runs.compare_schemas import (
    MetricsRowOut,
    TreeJson,
)
from app.runs.schemas import CheckpointOut, RunCreate, RunCreated, RunOut
from engine.treefile import tree_to_json

router = APIRouter(prefix="/runs", tags=["runs"])


@router.post("", status_code=202)
def create_run(body: RunCreate, session: SessionDep, _: ResearcherDep) -> RunCreated:
    """Queue a training run; a worker starts it (``status`` goes ``queued`` -> ``running`` ->
    ``succeeded``, ``failed``, ``cancelled`` or ``interrupted``)."""
    run = runs.create_run(session, spec=body.spec())
    return RunCreated(id=run.id, status=RunStatus(run.status))


@router.get("")
def list_runs(
    session: SessionDep,
    _: ResearcherDep,
    study_id: DbId | None = None,
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
def resume_run(run_id: DbId, session: SessionDep, _: ResearcherDep) -> RunOut:
    """Queue an interrupted, failed or cancelled run again; it continues from its latest
    checkpoint exactly as if it had never stopped."""
    return RunOut.of(runs.resume_run(session, run_id=run_id))


@router.get("/{run_id}/metrics")
def run_metrics(
    run_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    after: Annotated[int, IntParam(ge=-1, le=MAX_STEP)] = -1,
) -> list[MetricsRowOut]:
    """The run's metrics rows (one per update) with ``timesteps`` above ``after``."""
    runs.get_run(session, run_id=run_id)
    rows = run_state.metrics_rows(session, run_id=run_id, after=after)
    return [MetricsRowOut.model_validate(row) for row in rows]


@router.get("/{run_id}/checkpoints")
def run_checkpoints(run_id: DbId, session: SessionDep, _: ResearcherDep) -> list[CheckpointOut]:
    """The run's checkpoints, oldest first."""
    runs.get_run(session, run_id=run_id)
    rows = {r["timesteps"]: r for r in run_state.metrics_rows(session, run_id=run_id)}
    steps = run_state.checkpoint_steps(session, run_id=run_id)
    return [CheckpointOut(checkpoint=s, metrics=rows.get(s)) for s in steps]


@router.get("/{run_id}/advice-tree")
def advice_tree(run_id: DbId, session: SessionDep, _: ResearcherDep) -> TreeJson:
    """The advice the run trains with (its Human Preference Tree), ``acv.tree/1``."""
    return tree_to_json(runs.advice_of(runs.get_run(session, run_id=run_id)))
