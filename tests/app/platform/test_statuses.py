"""Run and study statuses are defined once (StrEnums in app.models), and so are algorithms,
advice modes and teachers (in the engine); the CHECK constraints, the API's schemas and the
queue's groups use them."""

from __future__ import annotations

from enum import StrEnum

import pytest

from app.models import RUN_STATUSES, STUDY_STATUSES, Run, RunStatus, Study, StudyStatus
from app.runs.artefacts import ENDED
from app.runs.schemas import RunCreate, RunOut
from app.runs.service import FINAL, RESUMABLE
from app.studies.schemas import StudyOut
from engine.rl.config import ADVICE_MODES, ALGOS
from engine.teachers import TEACHERS


def _status_check(table) -> str:
    return next(
        str(c.sqltext)
        for c in table.constraints
        if str(getattr(c, "sqltext", "")).startswith("status IN")
    )


def test_constraints_and_literals_list_every_member() -> None:
    assert RUN_STATUSES == ("queued", "running", "succeeded", "failed", "cancelled", "interrupted")
    assert STUDY_STATUSES == ("preparing", "ready", "failed")
    assert _status_check(Run.__table__) == f"status IN ({', '.join(map(repr, RUN_STATUSES))})"
    assert _status_check(Study.__table__) == f"status IN ({', '.join(map(repr, STUDY_STATUSES))})"


def test_groups_are_members() -> None:
    assert set(RESUMABLE) | set(FINAL) | set(ENDED) <= set(RunStatus)
    assert RunStatus.RUNNING not in ENDED and RunStatus.QUEUED not in RESUMABLE
    assert StudyStatus("ready") is StudyStatus.READY


@pytest.mark.parametrize(
    ("model", "field", "values"),
    [
        (RunOut, "status", RUN_STATUSES),
        (StudyOut, "status", STUDY_STATUSES),
        (RunCreate, "algo", ALGOS),
        (RunCreate, "advice_mode", ADVICE_MODES),
        (RunCreate, "teacher", TEACHERS),
    ],
)
def test_the_api_schemas_use_the_enums(model, field: str, values: tuple[str, ...], client) -> None:
    annotation = model.model_fields[field].annotation
    enum = next(a for a in (annotation, *getattr(annotation, "__args__", ())) if _is_enum(a))
    assert tuple(m.value for m in enum) == values
    components = client.get("/openapi.json").json()["components"]["schemas"]
    assert tuple(components[enum.__name__]["enum"]) == values


def _is_enum(annotation: object) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, StrEnum)
