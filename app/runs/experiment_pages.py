"""The experiment page: its runs by role and seed, live, and the verdict for a judge. An
external experiment's runs are imported policies, shown with their declared training settings
beside the words that ACV did not see them train.

The page is rendered with the state of the moment; ``static/js/experiment.js`` then polls
``/api/experiments/{id}`` and its verdict until every run has ended.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.responses import HTMLResponse

from app.evaluations import researcher_pages
from app.http.deps import DbId, SessionDep
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute, render
from app.models import ExperimentRole
from app.runs import experiments, verdicts
from app.runs import service as runs
from app.runs.compare_pages import JUDGE_LABELS
from app.runs.external import advice_label as external_advice
from app.runs.external import external_info
from app.runs.imported import is_external
from app.runs.imported_schemas import NOT_SEEN, ImportedOut
from app.runs.schemas import Judge
from app.studies import service as studies
from engine.errors import InputError
from engine.judges import DEFAULT_JUDGE, VERDICT_JUDGES, judge_name

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])


@router.get("/experiments/{experiment_id}")
def experiment_page(
    experiment_id: DbId,
    request: Request,
    session: SessionDep,
    judge: Annotated[Judge, Query()] = DEFAULT_JUDGE,
) -> HTMLResponse:
    experiment = experiments.get_experiment(session, experiment_id=experiment_id)
    members = experiments.members(session, experiment_id=experiment_id)
    advised = next((run for role, run in members if role == ExperimentRole.ADVISED), None)
    external = is_external(experiment)
    try:
        found = verdicts.experiment_verdict(session, experiment_id=experiment_id, judge=judge)
        problem = None
    except InputError as exc:  # checkpoints judged before this judge existed
        found, problem = None, str(exc)
    return render(
        request,
        "experiment.html",
        {
            "experiment": experiment,
            "study": studies.get_study(session, study_id=experiment.study_id),
            "members": members,
            "advice": external_advice(experiment)
            if external or advised is None
            else runs.advice_label(advised),
            "algo": None if advised is None else advised.algo,
            "judge": judge_name(judge),
            "judges": [j for j in JUDGE_LABELS if not external or j[0] in VERDICT_JUDGES],
            "external": external_info(experiment) if external else None,
            "imported": {run.id: ImportedOut.of(run) for _, run in members},
            "not_seen": NOT_SEEN,
            "found": found,
            "problem": problem,
            **researcher_pages.experiment_section(session, experiment_id),
        },
    )
