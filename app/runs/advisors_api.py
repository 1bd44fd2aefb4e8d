"""``/api/runs/{id}/advisors``: a run on pooled advice, the agent against each participant.

Read from the checkpoint's artefact, which the run's executor stores (202 until then), like
the other comparison endpoints of :mod:`app.runs.api`.
"""

from __future__ import annotations

from fastapi import APIRouter

from app.core.errors import ConflictError
from app.http.deps import DbId, ResearcherDep, SessionDep
from app.runs.api import PENDING, JudgeQuery, RunsRootDep, Step, load_view
from app.runs.compare_schemas import AdvisorsOut
from app.runs.pools import members
from engine.judges import DEFAULT_JUDGE

router = APIRouter(prefix="/runs", tags=["runs"])


@router.get("/{run_id}/advisors", responses=PENDING)
def advisors(
    run_id: DbId,
    session: SessionDep,
    root: RunsRootDep,
    _: ResearcherDep,
    checkpoint: Step = None,
    judge: JudgeQuery = DEFAULT_JUDGE,
) -> AdvisorsOut:
    """The agent's tree at a checkpoint against each pooled participant's tree, and against
    the pooled verdict; 409 for a run not on pooled advice."""
    run, view = load_view(session, run_id, root, checkpoint)
    if members(run) is None:
        raise ConflictError(f"run {run_id} is not trained on pooled advice")
    return AdvisorsOut.of(view, judge)
