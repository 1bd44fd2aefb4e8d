"""``/api/experiments``: advised runs on k seeds with a matched no-advice baseline, and the
verdict that compares them (docs/method.md §2.11).

``POST`` queues the runs (202); the verdict answers 202 ``{"status": "pending"}`` until enough
runs of every role have a judged checkpoint, then the verdict at the latest such step. A
``step`` asked for that no run of the experiment has saved is a 404.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from sqlalchemy.orm import Session

from app.core.csv_export import csv_text
from app.core.json_types import UtcDatetime
from app.core.rows import from_row
from app.http.deps import DbId, ResearcherDep, SessionDep, StepParam
from app.http.errors import RESPONSES
from app.http.files import attachment
from app.models import Experiment, ExperimentRole, RunStatus
from app.runs import experiment_notes, experiments, external, verdicts
from app.runs.imported import public_spec, tree_digest
from app.runs.imported_schemas import ImportedOut
from app.runs.schemas import ExperimentCreate, Judge
from app.studies.schemas import ProgressOut
from engine.judges import DEFAULT_JUDGE
from engine.rl.config import Algo
from engine.treefile import dumps

router = APIRouter(prefix="/experiments", tags=["experiments"])
PENDING: dict[int | str, dict[str, Any]] = {
    202: {"description": 'Not enough runs judged yet: {"status": "pending"}; ask again.'},
    404: {
        **RESPONSES[404],
        "description": "No such experiment, or ``step`` is no checkpoint of its runs.",
    },
}


class ExperimentRunOut(BaseModel):
    id: int
    role: ExperimentRole
    algo: Algo
    seed: int
    status: RunStatus
    progress: ProgressOut
    imported: ImportedOut | None = Field(
        None, description="An imported policy's declared settings (null for ACV's own runs)."
    )


class ExperimentOut(BaseModel):
    """An experiment: what its runs train, their seeds, and where each run stands."""

    id: int
    study_id: int
    spec: dict[str, Any] = Field(description="The advised runs' request, less the seed.")
    seeds: list[int]
    pilot_seeds: list[int]
    created_at: UtcDatetime
    runs: list[ExperimentRunOut]
    verdict_url: str = Field(
        description="Its verdict (GET; 202 until enough runs of every role are judged); "
        "`verdict.csv` beside it gives the same as CSV."
    )


class VerdictOut(BaseModel):
    """The verdict of one judge at one checkpoint step (see ``engine.verdict.Verdict``)."""

    judge: str
    step: int
    runs: dict[ExperimentRole, list[int]] = Field(description="The run ids it rests on, by role.")
    verdict: dict[str, Any]
    final: bool = Field(
        description="It rests on every run of the experiment, each ended at its last "
        "checkpoint. An earlier look is interim: its outcome is not the experiment's verdict."
    )
    diagnostic: bool = Field(
        description="Its judge never decides a verdict (only `behaviour` and `return` do): "
        "its outcome is for comparison only."
    )


def experiment_out(session: Session, experiment: Experiment) -> ExperimentOut:
    """The experiment's answer (an external one's frozen advice tree left out)."""
    runs = [
        ExperimentRunOut(
            id=run.id,
            role=role,  # type: ignore[arg-type]  # the CHECK constraint keeps it one of three
            algo=run.algo,
            seed=run.seed,
            status=run.status,
            progress=ProgressOut(done=run.progress, total=run.timesteps),
            imported=ImportedOut.of(run),
        )
        for role, run in experiments.members(session, experiment_id=experiment.id)
    ]
    created: datetime = experiment.created_at
    url = f"/api/experiments/{experiment.id}/verdict"
    return from_row(
        ExperimentOut,
        experiment,
        spec=public_spec(experiment.spec),
        created_at=created,
        runs=runs,
        verdict_url=url,
    )


@router.post("", status_code=202)
def create_experiment(
    body: ExperimentCreate, session: SessionDep, _: ResearcherDep
) -> ExperimentOut:
    """Queue the advised runs, and the baseline and pilot runs not trained already (runs of
    the same study, config and seed are reused)."""
    experiment = experiments.create_experiment(session, spec=body.experiment_spec())
    return experiment_out(session, experiment)


@router.get("")
def list_experiments(
    session: SessionDep,
    _: ResearcherDep,
    study_id: DbId | None = None,
) -> list[ExperimentOut]:
    return [
        experiment_out(session, e) for e in experiments.list_experiments(session, study_id=study_id)
    ]


@router.get("/{experiment_id}")
def get_experiment(experiment_id: DbId, session: SessionDep, _: ResearcherDep) -> ExperimentOut:
    return experiment_out(session, experiments.get_experiment(session, experiment_id=experiment_id))


TREE_HEADERS = {
    "X-Tree-SHA256": {
        "description": "SHA-256 (hex) of the body: the experiment's ``spec.tree_sha256`` for "
        "an external one, what a policy trained with it declares.",
        "schema": {"type": "string"},
    },
    "ETag": {"description": "The same hash, quoted.", "schema": {"type": "string"}},
}


@router.get(
    "/{experiment_id}/advice-tree",
    response_class=Response,
    responses={
        200: {
            "description": "The ``acv.tree/1`` document (``AdviceWrapper`` loads it).",
            "content": {"application/json": {}},
            "headers": TREE_HEADERS,
        },
        404: {**RESPONSES[404], "description": "No such experiment."},
        409: {**RESPONSES[409], "description": "Its advised runs have no advice tree."},
    },
)
def experiment_advice_tree(experiment_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """The advice tree to train the advised arm with elsewhere (``acv.tree/1``, as ACV writes
    the file, so that ``sha256sum`` of the download gives the ``X-Tree-SHA256`` header)."""
    doc = external.experiment_advice(session, experiment_id=experiment_id)
    digest = tree_digest(doc)
    return Response(
        dumps(doc),
        media_type="application/json",
        headers={"X-Tree-SHA256": digest, "ETag": f'"{digest}"'},
    )


JudgeQuery = Annotated[Judge, Query(description="How the runs score states.")]
StepQuery = Annotated[StepParam | None, Query(description="Checkpoint (default: latest).")]


@router.get("/{experiment_id}/verdict", responses=PENDING)
def experiment_verdict(
    experiment_id: DbId,
    session: SessionDep,
    response: Response,
    _: ResearcherDep,
    judge: JudgeQuery = DEFAULT_JUDGE,
    step: StepQuery = None,
) -> VerdictOut | dict[str, str]:
    """Advised runs against the matched baseline at one checkpoint step, for one judge."""
    found = verdicts.experiment_verdict(
        session, experiment_id=experiment_id, judge=judge, step=step
    )
    if found is None:
        response.status_code = 202
        return {"status": "pending"}
    return VerdictOut(
        judge=found.judge,
        step=found.step,
        runs=found.runs,
        verdict=found.verdict.to_json(),
        final=found.final,
        diagnostic=found.diagnostic,
    )


@router.get(
    "/{experiment_id}/verdict.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}, **PENDING},
)
def experiment_verdict_csv(
    experiment_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    judge: JudgeQuery = DEFAULT_JUDGE,
    step: StepQuery = None,
) -> Response:
    """The verdict as CSV, one row per run it rests on: role, seed and the run's share of the
    contested matches kept (CA), with Δ, its interval, p, AUC and the outcome on every row."""
    found = verdicts.experiment_verdict(
        session, experiment_id=experiment_id, judge=judge, step=step
    )
    if found is None:
        return JSONResponse({"status": "pending"}, status_code=202)
    rows = experiment_notes.verdict_rows(session, experiment_id=experiment_id, found=found)
    name = f"experiment-{experiment_id}-verdict-{found.judge}-step{found.step}.csv"
    return attachment(csv_text(experiment_notes.CSV_HEADER, rows), "text/csv", name)
