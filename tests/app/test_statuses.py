"""Run and study statuses are defined once (StrEnums in app.models); the CHECK constraints,
the API's Literal types and the queue's groups are derived from them."""

from __future__ import annotations

from typing import get_args

from app.api.run_schemas import RunStatus as RunStatusLiteral
from app.api.schemas import StudyStatus as StudyStatusLiteral
from app.models import RUN_STATUSES, STUDY_STATUSES, Run, RunStatus, Study, StudyStatus
from app.services.artefacts import ENDED
from app.services.runs import FINAL, RESUMABLE


def _status_check(table) -> str:
    return next(
        str(c.sqltext)
        for c in table.constraints
        if str(getattr(c, "sqltext", "")).startswith("status IN")
    )


def test_constraints_and_literals_list_every_member() -> None:
    assert RUN_STATUSES == ("queued", "running", "succeeded", "failed", "cancelled", "interrupted")
    assert STUDY_STATUSES == ("preparing", "ready", "failed")
    assert get_args(RunStatusLiteral) == RUN_STATUSES
    assert get_args(StudyStatusLiteral) == STUDY_STATUSES
    assert _status_check(Run.__table__) == f"status IN ({', '.join(map(repr, RUN_STATUSES))})"
    assert _status_check(Study.__table__) == f"status IN ({', '.join(map(repr, STUDY_STATUSES))})"


def test_groups_are_members() -> None:
    assert set(RESUMABLE) | set(FINAL) | set(ENDED) <= set(RunStatus)
    assert RunStatus.RUNNING not in ENDED and RunStatus.QUEUED not in RESUMABLE
    assert StudyStatus("ready") is StudyStatus.READY
