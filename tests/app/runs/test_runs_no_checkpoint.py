"""A run with no checkpoint yet is a state, not bad input: every operation on its checkpoint
answers 409, as the OpenAPI document says (issue 24); while a saved checkpoint is being
judged, each answers 202, documented too (issue 45 §6: ``report.html`` did not say so). On
PostgreSQL."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from app.models import RunCheckpoint
from tests.support.runs import TINY, create_run, finished_participant, run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only

#: Every operation that reads a checkpoint of a run (the latest one when none is named).
ON_A_CHECKPOINT = [
    "/api/runs/{run_id}/agent-tree",
    "/api/runs/{run_id}/conformance",
    "/api/runs/{run_id}/checkpoint-report",
    "/api/runs/{run_id}/conformance.csv?checkpoint=256",
    "/api/runs/{run_id}/trees/agent.svg",
    "/api/runs/{run_id}/report.html",
    "/api/runs/{run_id}/advisors",
]


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    """The app with no run worker: a run stays queued, with no checkpoint."""
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def queued_run(client: TestClient) -> int:
    study = new_study(client)
    participant = finished_participant(client, study["id"])
    return create_run(
        client, study_id=study["id"], participant_id=participant, timesteps=1024, **TINY
    )


@pytest.mark.parametrize("path", ON_A_CHECKPOINT)
def test_no_checkpoint_yet_is_409(client: TestClient, queued_run: int, path: str) -> None:
    response = client.get(path.format(run_id=queued_run), headers=ADMIN)
    assert response.status_code == 409, response.text
    assert response.json() == {"detail": "the run has no checkpoint yet"}


@pytest.mark.parametrize("path", ON_A_CHECKPOINT)
def test_the_schema_documents_the_409(client: TestClient, path: str) -> None:
    template = path.split("?")[0].replace("agent.svg", "{which}.{fmt}")
    operation = client.app.openapi()["paths"][template]["get"]
    assert "no checkpoint yet" in operation["responses"]["409"]["description"]


@pytest.fixture(scope="module")
def judging_run(client: TestClient) -> int:
    """A run whose checkpoint 256 is saved and not judged yet (no artefact stored)."""
    study = new_study(client)
    participant = finished_participant(client, study["id"])
    run_id = create_run(
        client, study_id=study["id"], participant_id=participant, timesteps=1024, **TINY
    )
    with client.app.state.runtime.sessions() as session:  # as the executor records it
        session.add(RunCheckpoint(run_id=run_id, step=256))
        session.commit()
    return run_id


@pytest.mark.parametrize("path", ON_A_CHECKPOINT)
def test_a_checkpoint_being_judged_is_a_documented_202(
    client: TestClient, judging_run: int, path: str
) -> None:
    response = client.get(path.format(run_id=judging_run), headers=ADMIN)
    assert response.status_code == 202, response.text
    assert response.json()["status"] == "pending"
    template = path.split("?")[0].replace("agent.svg", "{which}.{fmt}")
    operation = client.app.openapi()["paths"][template]["get"]
    assert "pending" in operation["responses"]["202"]["description"]
