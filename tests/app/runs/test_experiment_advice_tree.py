"""``GET /api/experiments/{id}/advice-tree`` when there is no tree to give (issue 44): an
experiment whose advised arm is missing, or whose advised runs train without advice, is a
409 naming why, to researchers only. (The download itself, its hash headers, the 404 and the
anonymous 401 are in tests/app/runs/test_agents_api.py.)

``POST /api/experiments`` never stores such an experiment (it always queues advised runs on
advice), so the rows are written as a migration or a hand edit would leave them."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.models import Experiment, ExperimentRole, ExperimentRun, Run
from tests.support.runs import TINY, run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, n_candidates=4, seed=44)


@pytest.fixture(scope="module")
def plain_run(client: TestClient, study: dict[str, Any]) -> int:
    """A ``ppo`` run with no advice (it never trains: the worker is off)."""
    body = {"study_id": study["id"], "seed": 0, "algo": "ppo", "timesteps": 512, **TINY}
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == 202, response.text
    run_id = int(response.json()["id"])
    with client.app.state.runtime.sessions() as session:
        run = session.get(Run, run_id)
        assert run is not None and run.advice is None
    return run_id


def _experiment(client: TestClient, study_id: int, members: dict[int, ExperimentRole]) -> int:
    """An experiment (trained here, not external) of these ``{run id: role}``."""
    with client.app.state.runtime.sessions() as session, session.begin():
        experiment = Experiment(study_id=study_id, spec={}, seeds=[0], pilot_seeds=[])
        session.add(experiment)
        session.flush()
        for run_id, role in members.items():
            session.add(ExperimentRun(experiment_id=experiment.id, run_id=run_id, role=role))
        return experiment.id


def _advice_tree(client: TestClient, experiment_id: int, **kwargs: Any) -> Any:
    return client.get(f"/api/experiments/{experiment_id}/advice-tree", **kwargs)


@pytest.mark.parametrize(
    ("role", "says"),
    [
        (ExperimentRole.BASELINE, "has no advised runs"),
        (ExperimentRole.ADVISED, "has no advice tree"),
    ],
)
def test_no_advice_tree_to_give_is_409_naming_why(
    client: TestClient, study: dict[str, Any], plain_run: int, role: ExperimentRole, says: str
) -> None:
    experiment_id = _experiment(client, study["id"], {plain_run: role})
    response = _advice_tree(client, experiment_id, headers=ADMIN)
    assert response.status_code == 409, response.text
    assert response.headers["content-type"].startswith("application/json")
    detail = response.json()["detail"]
    assert says in detail
    named = f"experiment {experiment_id}" if role == ExperimentRole.BASELINE else f"run {plain_run}"
    assert named in detail
    assert "x-tree-sha256" not in response.headers and "etag" not in response.headers
    # a caller who is not the researcher learns nothing of it
    assert _advice_tree(client, experiment_id).status_code == 401
    wrong = _advice_tree(client, experiment_id, headers={"Authorization": "Bearer not-the-token"})
    assert wrong.status_code == 401
    assert "advice" not in wrong.json()["detail"]


def test_an_experiment_with_no_runs_at_all_is_409_too(
    client: TestClient, study: dict[str, Any]
) -> None:
    experiment_id = _experiment(client, study["id"], {})
    response = _advice_tree(client, experiment_id, headers=ADMIN)
    assert response.status_code == 409, response.text
    assert response.json() == {"detail": f"experiment {experiment_id} has no advised runs"}


def test_an_unknown_experiment_is_404_and_needs_the_researcher(client: TestClient) -> None:
    missing = _advice_tree(client, 999_999, headers=ADMIN)
    assert missing.status_code == 404 and "999999" in missing.json()["detail"]
    assert _advice_tree(client, 999_999).status_code == 401
