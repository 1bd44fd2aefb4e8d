"""The demo study of ``acv serve --demo`` (``make run``): prepared once, with a simulated
finished participant, an unused invite, and an experiment on that participant's advice whose
runs the server's worker trains (here the worker is off, so they stay queued)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from app.cli.serve import _demo_lines
from app.demo import DEMO_RUN, ensure_demo
from app.labelling.participants import invite_url
from tests.support.runs import run_app
from tests.support.web import ADMIN


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


def test_the_demo_is_prepared_once_with_its_experiment(client: TestClient) -> None:
    runtime = client.app.state.runtime
    first, again = ensure_demo(runtime), ensure_demo(runtime)
    assert (again.study.id, again.simulated.id, again.experiment_id) == (
        first.study.id,
        first.simulated.id,
        first.experiment_id,
    )
    assert again.invite_token == first.invite_token  # still unused
    study = client.get(f"/api/studies/{first.study.id}", headers=ADMIN).json()
    assert (study["env_id"], study["n_candidates"], study["status"]) == ("Humanoid-v5", 16, "ready")
    experiments = client.get(f"/api/experiments?study_id={first.study.id}", headers=ADMIN).json()
    assert [e["id"] for e in experiments] == [first.experiment_id]
    (experiment,) = experiments
    roles = [r["role"] for r in experiment["runs"]]
    assert (roles.count("advised"), roles.count("baseline"), roles.count("pilot")) == (5, 5, 2)
    assert experiment["spec"]["participant_id"] == first.simulated.id
    assert {k: experiment["spec"][k] for k in DEMO_RUN} == DEMO_RUN
    assert all(r["status"] == "queued" for r in experiment["runs"])


def test_serve_prints_where_the_demo_is(client: TestClient) -> None:
    lines = _demo_lines(client.app.state.runtime, "http://127.0.0.1:8000")
    demo = ensure_demo(client.app.state.runtime)
    assert f"http://127.0.0.1:8000/studies/{demo.study.id}" in lines[0]
    assert invite_url("http://127.0.0.1:8000", demo.invite_token) in lines[1]
    assert f"http://127.0.0.1:8000/experiments/{demo.experiment_id}" in lines[2]
