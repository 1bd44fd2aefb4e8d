"""Experiments through the API: advised runs on k seeds, a matched baseline that is shared,
pilot runs, and the verdict read from the runs' stored checkpoint artefacts (issue 25 §1).

No run trains here (the run worker is off): each run's artefact is written as its executor
would write it, with per-candidate scores whose truth is known, so the verdict's outcome is
known. Training and judging for real are covered by the runs tests and the browser test.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from app.models import Run
from app.services import artefacts
from engine.rl.report import SCHEMA
from tests.app.conftest import ADMIN, new_study
from tests.app.runs_support import TINY, run_app

BODY = {"algo": "bipars-em", "timesteps": 512, **TINY}
STEP = 256


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, n_candidates=8, seed=11)


def _create(client: TestClient, status: int = 202, **body: Any) -> dict[str, Any]:
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert response.status_code == status, response.text
    return response.json()


def _n_runs(client: TestClient) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(select(func.count()).select_from(Run))


def _write_artefact(client: TestClient, run_id: int, step: int, behaviour: np.ndarray) -> None:
    """The run's report at ``step`` as its executor stores it (only the table matters here)."""
    rows = [
        {
            "id": i,
            "reward": 0.0,
            "advice": 0.0,
            "z": 0.0,
            "shaping": 0.0,
            "shaped": 0.0,
            "value": 0.0,
            "behaviour": float(score),
        }
        for i, score in enumerate(behaviour)
    ]
    body = {"schema": SCHEMA, "step": step, "judges": {}, "candidates": rows}
    with client.app.state.runtime.sessions() as session:
        assert artefacts.store(session, run_id=run_id, step=step, body=body)


def test_an_experiment_queues_advised_baseline_and_pilot_runs(client, study) -> None:
    created = _create(client, study_id=study["id"], teacher="good", seeds=3, pilot_seeds=2, **BODY)
    roles = [(r["role"], r["algo"], r["seed"]) for r in created["runs"]]
    assert roles == [
        ("advised", "bipars-em", 0),
        ("advised", "bipars-em", 1),
        ("advised", "bipars-em", 2),
        ("baseline", "ppo", 0),
        ("baseline", "ppo", 1),
        ("baseline", "ppo", 2),
        ("pilot", "ppo", 1_000_000),
        ("pilot", "ppo", 1_000_001),
    ]
    assert all(r["status"] == "queued" for r in created["runs"])
    assert created["seeds"] == [0, 1, 2] and created["pilot_seeds"] == [1_000_000, 1_000_001]
    # Another advice source with the same settings reuses the baseline and pilot runs.
    before = _n_runs(client)
    other = _create(
        client, study_id=study["id"], teacher="standing", seeds=3, pilot_seeds=2, **BODY
    )
    assert _n_runs(client) == before + 3  # its own advised runs only
    shared = lambda e: [r["id"] for r in e["runs"] if r["role"] != "advised"]  # noqa: E731
    assert shared(other) == shared(created)
    # Other settings (the budget) are another baseline.
    third = _create(
        client,
        study_id=study["id"],
        teacher="good",
        seeds=2,
        pilot_seeds=1,
        **{**BODY, "timesteps": 1024},
    )
    assert not set(shared(third)) & set(shared(created))
    listed = client.get(f"/api/experiments?study_id={study['id']}", headers=ADMIN).json()
    assert [e["id"] for e in listed] == [created["id"], other["id"], third["id"]]


def test_the_verdict_waits_for_judged_runs_then_says_used(client, study) -> None:
    experiment = _create(
        client,
        study_id=study["id"],
        teacher="good",
        seeds=5,
        pilot_seeds=1,
        **{**BODY, "timesteps": 768},
    )
    path = f"/api/experiments/{experiment['id']}/verdict?judge=behaviour"
    assert client.get(path, headers=ADMIN).status_code == 202
    advice = np.array(
        [
            c["env_reward"]
            for c in client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
        ]
    )
    rng = np.random.default_rng(0)
    for run in experiment["runs"]:  # advised runs follow the advice, the others go against it
        sign = 1.0 if run["role"] == "advised" else -1.0
        _write_artefact(client, run["id"], STEP, sign * advice + rng.normal(0, 1e-3, advice.size))
    _write_artefact(client, experiment["runs"][0]["id"], 2 * STEP, advice)  # one run further
    response = client.get(path, headers=ADMIN)
    assert response.status_code == 200, response.text
    body = response.json()
    assert body["step"] == STEP  # the latest step judged in enough runs of every role
    assert sorted(body["runs"]) == ["advised", "baseline", "pilot"]
    verdict = body["verdict"]
    assert verdict["outcome"] == "used", verdict
    assert verdict["ca_advised"] == [1.0] * 5 and verdict["ca_baseline"] == [0.0] * 5
    assert verdict["p_value"] < 0.05 and verdict["n_contested"] >= 3


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"algo": "ppo"}, "algo other than ppo"),
        ({"seeds": 1}, "seeds"),
        ({"seeds": 21}, "seeds"),
        ({"seeds": True}, "seeds"),
        ({"pilot_seeds": 0}, "pilot_seeds"),
        ({"teacher": "nobody"}, "teacher"),
        ({"teacher": None}, "advice"),
        ({"study_id": 999_999}, "study"),
    ],
)
def test_bad_experiments_are_refused_and_queue_nothing(client, study, change, says) -> None:
    before = _n_runs(client)
    body = {"study_id": study["id"], "teacher": "good", **BODY, **change}
    response = client.post("/api/experiments", json=body, headers=ADMIN)
    assert 400 <= response.status_code < 500 and says in response.text, response.text
    assert _n_runs(client) == before


def test_unknown_experiments_and_judges(client, study) -> None:
    assert client.get("/api/experiments/999999", headers=ADMIN).status_code == 404
    assert client.get("/api/experiments/999999/verdict", headers=ADMIN).status_code == 404
    experiment = _create(client, study_id=study["id"], teacher="good", seeds=2, **BODY)
    response = client.get(
        f"/api/experiments/{experiment['id']}/verdict?judge=psychic", headers=ADMIN
    )
    assert response.status_code == 422
    assert client.get("/api/experiments", headers={}).status_code == 401
