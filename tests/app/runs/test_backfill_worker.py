"""The idle worker judges what the executor did not: the checkpoint a stop writes.

A cancelled run's last checkpoint is written by the stop, which skips judging to stay quick;
the server's worker, once idle, finds it and judges it in a backfill process of its own, so
the compare page never waits for ever. Runs on PostgreSQL.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from tests.support.runs import ENDLESS, create_run, progressed, run_app, wait_run
from tests.support.studies import new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]
# postgres_only: training is the subject, not storage.


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, backfill_s=0.2) as test_client:
        yield test_client


def test_the_checkpoint_a_stop_writes_is_judged_by_the_idle_worker(client: TestClient) -> None:
    study = new_study(client)
    run_id = create_run(
        client, study_id=study["id"], teacher="standing", algo="bipars-em", **ENDLESS
    )
    wait_run(client, run_id, progressed)
    assert client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN).status_code == 202
    assert wait_run(client, run_id)["status"] == "cancelled"
    checkpoints = client.get(f"/api/runs/{run_id}/checkpoints", headers=ADMIN).json()
    last = checkpoints[-1]["checkpoint"]

    def agent_tree() -> int:
        url = f"/api/runs/{run_id}/agent-tree?checkpoint={last}&judge=behaviour"
        response = client.get(url, headers=ADMIN)
        assert response.status_code in (200, 202), response.text
        return response.status_code

    wait_for(
        agent_tree, lambda status: status == 200, what="the stop's checkpoint judged", timeout_s=180
    )
    curve = client.get(f"/api/runs/{run_id}/conformance-curve", headers=ADMIN).json()
    assert [p["checkpoint"] for p in curve] == [c["checkpoint"] for c in checkpoints]
