"""``/api/runs/{id}/advisors``: a run on pooled advice, the agent against each participant.

Read from the checkpoint's artefact, which the run's executor stores (202 until then), like
the other comparison endpoints of :mod:`app.runs.checkpoint_api`.
"""

from __future__ import annotations

from fastapi import APIRouter

from app.core.errors import ConflictError
from app.runs.checkpoint_api import PENDING, AtCheckpointDep
from app.runs.compare_schemas import AdvisorsOut
from app.runs.pools import members

router = APIRouter(prefix="/runs", tags=["runs"])


@router.get("/{run_id}/advisors", responses=PENDING)
def advisors(at: AtCheckpointDep) -> AdvisorsOut:
    """The agent's tree at a checkpoint against each pooled participant's tree, and against
    the pooled verdict; 409 for a run not on pooled advice."""
    run, view = at.view()
    if members(run) is None:
        raise ConflictError(f"run {at.run_id} is not trained on pooled advice")
    return AdvisorsOut.of(view, at.judge)
