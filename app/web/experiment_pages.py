"""The experiment page: its runs by role and seed, live, and the verdict for a judge.

The page is rendered with the state of the moment; ``static/js/experiment.js`` then polls
``/api/experiments/{id}`` and its verdict until every run has ended.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.responses import HTMLResponse

from app.api.deps import DbId, SessionDep
from app.api.experiments import VerdictJudge
from app.services import experiments, runs, studies
from app.web.guards import ResearcherPage
from app.web.rendering import PageRoute, render

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])

#: The judges a verdict may read, as the selector names them (the default first).
VERDICT_JUDGES = (
    ("behaviour", "its behaviour: which advised postures its own rollouts come near"),
    ("value", "its shaped critic V (reads the advice too: a diagnostic)"),
    ("shaped", "its shaped reward R + z F: is your advice still in its reward? (diagnostic)"),
    ("shaping", "the advice part z F (diagnostic)"),
)


@router.get("/experiments/{experiment_id}")
def experiment_page(
    experiment_id: DbId,
    request: Request,
    session: SessionDep,
    judge: Annotated[VerdictJudge, Query()] = "behaviour",
) -> HTMLResponse:
    experiment = experiments.get_experiment(session, experiment_id=experiment_id)
    members = experiments.members(session, experiment_id=experiment_id)
    advised = next(run for role, run in members if role == "advised")
    return render(
        request,
        "experiment.html",
        {
            "experiment": experiment,
            "study": studies.get_study(session, study_id=experiment.study_id),
            "members": members,
            "advice": runs.advice_label(advised),
            "algo": advised.algo,
            "judge": judge,
            "judges": VERDICT_JUDGES,
            "found": experiments.experiment_verdict(
                session, experiment_id=experiment_id, judge=judge
            ),
        },
    )
