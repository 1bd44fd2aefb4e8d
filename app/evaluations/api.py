"""``/api/evaluations`` and ``/api/experiments/{id}/evaluations``: the researcher's side of
an agent evaluation (issue 41): create it, invite evaluators, read the answer, export.

Creation answers 201 with ``status: preparing``; the stills render in the background, then
``ready`` (evaluators can be invited) or ``failed`` with ``error``.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session

from app.core.csv_export import csv_text
from app.evaluations import evaluators, results
from app.evaluations import service as evaluations
from app.evaluations.schemas import (
    EvaluationCreate,
    EvaluationDesign,
    EvaluationOut,
    EvaluatorOut,
    EvaluatorsCreate,
)
from app.http.deps import DbId, ResearcherDep, RuntimeDep, SessionDep
from app.http.files import attachment
from app.http.urls import member_invite_url
from app.models import Evaluator
from app.recruiting.members import EVALUATION
from app.runtime import Runtime

router = APIRouter(tags=["evaluations"])


@router.post("/experiments/{experiment_id}/evaluations", status_code=201)
def create_from_experiment(
    experiment_id: DbId,
    body: EvaluationDesign,
    session: SessionDep,
    runtime: RuntimeDep,
    _: ResearcherDep,
) -> EvaluationOut:
    """Evaluate an experiment's advised runs against its baseline runs (pilots left out), at
    each run's latest checkpoint."""
    advised, baseline = evaluations.experiment_arms(session, experiment_id=experiment_id)
    spec = body.spec(advised, baseline, experiment_id=experiment_id)
    return _created(session, runtime, spec)


@router.post("/evaluations", status_code=201)
def create_evaluation(
    body: EvaluationCreate, session: SessionDep, runtime: RuntimeDep, _: ResearcherDep
) -> EvaluationOut:
    """Evaluate any two groups of runs of one env, at each run's latest checkpoint."""
    spec = body.spec(body.advised_run_ids, body.baseline_run_ids)
    return _created(session, runtime, spec)


def _created(session: Session, runtime: Runtime, spec: evaluations.EvaluationSpec) -> EvaluationOut:
    evaluation = evaluations.create_evaluation(session, spec=spec)
    runtime.prepare_evaluation_later(evaluation.id)
    return EvaluationOut.model_validate(evaluation)


@router.get("/evaluations")
def list_evaluations(session: SessionDep, _: ResearcherDep) -> list[EvaluationOut]:
    return [EvaluationOut.model_validate(e) for e in evaluations.list_evaluations(session)]


@router.get("/evaluations/{evaluation_id}")
def get_evaluation(evaluation_id: DbId, session: SessionDep, _: ResearcherDep) -> EvaluationOut:
    found = evaluations.get_evaluation(session, evaluation_id=evaluation_id)
    return EvaluationOut.model_validate(found)


@router.get("/evaluations/{evaluation_id}/result")
def evaluation_result(evaluation_id: DbId, session: SessionDep, _: ResearcherDep) -> dict[str, Any]:
    """The answer so far: the difference in mean win rate over all opponents between the
    arms, its exact permutation p and bootstrap interval, the advised agents' win rate in
    between-arm pairs, the side bias of within-arm pairs, and the outcome in words. Until the
    design's evaluators have finished (`final`), `sentence` says the look is interim and
    `outcome` is only what the rule would say now."""
    return results.result(session, evaluation_id=evaluation_id).to_json()


@router.post("/evaluations/{evaluation_id}/evaluators", status_code=201)
def add_evaluators(
    evaluation_id: DbId,
    body: EvaluatorsCreate,
    request: Request,
    session: SessionDep,
    _: ResearcherDep,
) -> list[EvaluatorOut]:
    """Invite evaluators; each gets an invite link ``/v/<token>`` and their own pairs."""
    people = evaluators.add_evaluators(
        session, evaluation_id=evaluation_id, count=body.count, name=body.name
    )
    return [evaluator_out(request, session, p) for p in people]


@router.get("/evaluations/{evaluation_id}/evaluators")
def list_evaluators(
    evaluation_id: DbId, request: Request, session: SessionDep, _: ResearcherDep
) -> list[EvaluatorOut]:
    people = evaluators.list_evaluators(session, evaluation_id=evaluation_id)
    return [evaluator_out(request, session, p) for p in people]


def evaluator_out(request: Request, session: Session, person: Evaluator) -> EvaluatorOut:
    progress = evaluators.progress(session, evaluator_id=person.id)
    return EvaluatorOut(
        id=person.id,
        name=person.name,
        invite_url=member_invite_url(request, EVALUATION, person.token),
        done=progress.done,
        total=progress.total,
        finished=person.finished_at is not None,
        withdrawn=person.withdrawn_at is not None,
        excluded=person.excluded,
    )


@router.get(
    "/evaluations/{evaluation_id}/answers.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def answers_csv(evaluation_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """Every kept answer, one row per pair, with its slots' runs and arms and what was shown
    (``stimulus``, ``reminder``)."""
    evaluations.get_evaluation(session, evaluation_id=evaluation_id)
    rows = results.export_rows(session, evaluation_id=evaluation_id)
    return attachment(
        csv_text(results.EXPORT_COLUMNS, rows),
        "text/csv; charset=utf-8",
        f"evaluation-{evaluation_id}-answers.csv",
    )
