"""Imported policies judged for real (issue 44 §2): a worker claims each one as it claims a
queued run, rolls it out in a limited child process with the ``return`` and ``behaviour``
judges, and stores its one checkpoint's report; the external experiment's verdict then reads
those as it reads any run's, each at the steps its trainer declared. The same file imported
again is not simulated again (the rollouts are cached by its hash).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.agents import DECLARED, create_external, obs_norm, policy, upload
from tests.support.runs import run_app, wait_run
from tests.support.studies import new_study
from tests.support.web import ADMIN, audit, logged_in

pytestmark = [pytest.mark.postgres_only, pytest.mark.slow]  # judging, not storage, is the subject


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, slots=2) as test_client:
        yield test_client


def _rollouts(client: TestClient) -> list[str]:
    state = client.app.state
    folder = state.job_settings.runs_root(state.runtime.settings) / "policies" / "rollouts"
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


def _import_arms(client: TestClient, experiment: dict[str, Any]) -> list[dict[str, Any]]:
    """Two advised, two baseline and one pilot policy, declared at different steps."""
    eid, tree = experiment["id"], experiment["spec"]["tree_sha256"]
    arms = [
        ("advised", 0, {"tree_sha256": tree}),
        ("advised", 1, {"tree_sha256": tree, "steps": 90_000}),
        ("baseline", 0, {}),
        ("baseline", 1, {}),
        ("pilot", 100, {}),
    ]
    runs = []
    for i, (arm, seed, extra) in enumerate(arms):
        norm = obs_norm() if i == 2 else None
        response = upload(
            client, eid, policy(40 + i), norm=norm, arm=arm, seed=seed, **(DECLARED | extra)
        )
        assert response.status_code == 202, response.text
        runs.append(response.json())
    return runs


def test_imported_policies_are_judged_and_get_a_verdict(client: TestClient) -> None:
    study = new_study(client, seed=6)
    experiment = create_external(client, study["id"], seeds=2)
    runs = _import_arms(client, experiment)
    for run in runs:
        done = wait_run(client, run["id"], timeout_s=600)
        assert done["status"] == "succeeded", done["error"]
        assert done["progress"] == {"done": done["timesteps"], "total": done["timesteps"]}
        steps = client.get(f"/api/runs/{run['id']}/checkpoints", headers=ADMIN).json()
        assert [c["checkpoint"] for c in steps] == [done["timesteps"]]
    advised = runs[0]["id"]
    report = client.get(f"/api/runs/{advised}/checkpoint-report", headers=ADMIN).json()
    assert sorted(j["judge"] for j in report["judges"]) == ["behaviour", "return"]
    assert all(c["env_return"] is not None for c in report["candidates"])
    html_report = client.get(f"/api/runs/{advised}/report.html", headers=ADMIN)
    assert html_report.status_code == 200 and "ACV did not see them train" in html_report.text
    shaped = client.get(f"/api/runs/{advised}/agent-tree?judge=shaped", headers=ADMIN)
    assert shaped.status_code == 422 and "has no tree for judge 'shaped'" in shaped.text
    tree = client.get(f"/api/runs/{advised}/agent-tree?judge=behaviour", headers=ADMIN)
    assert tree.status_code == 200 and tree.json()["judge"] == "agent:behaviour@100000"
    for judge in ("return", "behaviour"):
        verdict = client.get(
            f"/api/experiments/{experiment['id']}/verdict?judge={judge}", headers=ADMIN
        )
        assert verdict.status_code == 200, verdict.text
        body = verdict.json()
        assert body["step"] == 100_000  # each policy at its own steps; the largest is shown
        assert {role: len(ids) for role, ids in body["runs"].items()} == {
            "advised": 2,
            "baseline": 2,
            "pilot": 1,
        }
        assert body["verdict"]["outcome"] in ("used", "against", "no-different", "cannot-tell")
    page = logged_in(client)
    html = page.get(f"/experiments/{experiment['id']}?judge=behaviour").text
    assert "At each policy's own checkpoint (the steps its trainer" in html
    assert 'id="verdict" class="verdict outcome-' in html
    assert audit(html) == []
    several = page.get(f"/runs/{advised}/compare-runs").text
    assert "return and behaviour only" in several and audit(several) == []
    compare = page.get(f"/runs/{advised}/compare").text
    assert (
        'data-checkpoints="100000"' in compare
        and f'data-experiment="{experiment["id"]}"' in compare
    )
    # The same file in another experiment on the same advice: judged from the cache.
    cached = _rollouts(client)
    assert len(cached) == 2 * len(runs)  # per policy: behaviour rollouts, returns from states
    again = create_external(client, study["id"], seeds=2)
    tree_hash = again["spec"]["tree_sha256"]
    rerun = upload(
        client, again["id"], policy(40), arm="advised", seed=0, tree_sha256=tree_hash, **DECLARED
    )
    assert rerun.status_code == 202, rerun.text
    assert wait_run(client, rerun.json()["id"], timeout_s=600)["status"] == "succeeded"
    assert _rollouts(client) == cached
