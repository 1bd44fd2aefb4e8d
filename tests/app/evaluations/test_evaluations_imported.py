"""Agent evaluations of policies imported from elsewhere (issues 41 and 44), on both
databases: an external experiment's ONNX policies become an evaluation whose stills are
rolled out in the judges' limited child process and rendered for real, and an evaluator sees
JPEG pictures of them; an evaluation may mix imported runs with ACV's own.

No policy is judged (the run worker is off): an imported run's one policy is stored when it is
uploaded, at its declared steps, and that is what is shown.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from PIL import Image

from app.evaluations import service
from app.jobs.settings import JobSettings
from tests.support.agents import DECLARED, create_external, obs_norm, policy, upload
from tests.support.evaluations import evaluable_experiment, wait_evaluation
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# process: each imported policy's rollouts start a child process. postgres_only: an
# evaluation's stimuli and answer are the subject, not storage.
pytestmark = [pytest.mark.process, pytest.mark.postgres_only]

#: What every evaluation here asks for: stills only (fast), 2 pairs per evaluator.
DESIGN = {"pairs_per_evaluator": 2, "stimulus": "still"}


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, seed=23)


@pytest.fixture(scope="module")
def external(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    """An external experiment of 2 advised and 2 baseline imported policies (one normalised),
    declared at different steps; none judged."""
    experiment = create_external(client, study["id"], seeds=2)
    tree = experiment["spec"]["tree_sha256"]
    arms = [
        ("advised", 0, {"tree_sha256": tree}),
        ("advised", 1, {"tree_sha256": tree, "steps": 90_000}),
        ("baseline", 0, {}),
        ("baseline", 1, {}),
    ]
    runs = []
    for i, (arm, seed, extra) in enumerate(arms):
        norm = obs_norm() if i == 2 else None
        fields = DECLARED | extra
        response = upload(
            client, experiment["id"], policy(60 + i), norm=norm, arm=arm, seed=seed, **fields
        )
        assert response.status_code == 202, response.text
        runs.append(response.json())
    return {"experiment": experiment, "runs": runs}


def _created(client: TestClient, url: str, body: dict[str, Any]) -> dict[str, Any]:
    response = client.post(url, json=DESIGN | body, headers=ADMIN)
    assert response.status_code == 201, response.text
    assert response.json()["status"] == "preparing"
    ready = wait_evaluation(client, response.json()["id"])
    assert ready["status"] == "ready" and ready["error"] is None, ready
    return ready


def _slots(client: TestClient, evaluation_id: int) -> list[dict[str, Any]]:
    response = client.get(f"/api/evaluations/{evaluation_id}/result", headers=ADMIN)
    assert response.status_code == 200, response.text
    slots: list[dict[str, Any]] = response.json()["slots"]
    return slots


def _answer_a_pair(client: TestClient, evaluation_id: int) -> None:
    """An evaluator's first pair: each side's still is a JPEG; the answer is taken."""
    response = client.post(
        f"/api/evaluations/{evaluation_id}/evaluators", json={"count": 1}, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    token = response.json()[0]["invite_url"].rsplit("/", 1)[1]
    headers = {"Authorization": f"Bearer {token}"}
    pair = client.get("/api/evaluators/me/pairs/next", headers=headers)
    assert pair.status_code == 200, pair.text
    for side in ("left", "right"):
        got = client.get(pair.json()[side]["still"], headers=headers)
        assert got.status_code == 200
        assert Image.open(io.BytesIO(got.content)).format == "JPEG"
    key = pair.json()["key"]
    answer = client.post(
        f"/api/evaluators/me/pairs/{key}", json={"choice": "left"}, headers=headers
    )
    assert answer.status_code == 200, answer.text


def test_an_external_experiment_becomes_an_evaluation(
    client: TestClient, external: dict[str, Any]
) -> None:
    experiment, runs = external["experiment"], external["runs"]
    evaluation = _created(client, f"/api/experiments/{experiment['id']}/evaluations", {})
    slots = _slots(client, evaluation["id"])
    assert sorted(s["run_id"] for s in slots) == sorted(r["id"] for r in runs)
    assert sum(s["advised"] for s in slots) == 2
    with client.app.state.runtime.sessions() as session:  # each at its declared steps
        steps = {s.run_id: s.step for s in service.slots(session, evaluation_id=evaluation["id"])}
    assert steps == {r["id"]: r["timesteps"] for r in runs}
    assert sorted(steps.values()) == [90_000, 100_000, 100_000, 100_000]
    _answer_a_pair(client, evaluation["id"])
    # Each policy was rolled out once: its windows are cached by its content and options
    state = client.app.state
    windows = state.runtime.settings.data_dir / "stimuli" / "windows"
    assert len(list(windows.glob("*.npz"))) == len(runs)
    runs_root = JobSettings().runs_root(state.runtime.settings)
    assert not (runs_root / "policies" / "rollouts").exists()  # the judges' cache is theirs


def test_imported_and_acv_runs_mix_in_one_evaluation(
    client: TestClient, study: dict[str, Any], external: dict[str, Any]
) -> None:
    imported = [r["id"] for r in external["runs"] if r["config"]["imported"]["arm"] == "advised"]
    acv = evaluable_experiment(client, study["id"], seeds=2)
    baseline = [r["id"] for r in acv["runs"] if r["role"] == "baseline"]
    body = {"advised_run_ids": imported, "baseline_run_ids": baseline}
    evaluation = _created(client, "/api/evaluations", body)
    slots = _slots(client, evaluation["id"])
    assert sorted(s["run_id"] for s in slots) == sorted(imported + baseline)
    _answer_a_pair(client, evaluation["id"])
