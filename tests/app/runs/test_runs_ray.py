"""The ``ray`` executor against a real Ray instance that the test starts on 127.0.0.1.

``ray start --head --block`` runs in its own session with its own temp dir; the app, given
``ACV_RAY_ADDRESS`` (here ``JobSettings(ray_address=...)``), runs every claimed run as a Ray
task that reports to the database: a tiny run succeeds with its checkpoints and agent tree,
and a long one stops with a checkpoint when it is cancelled. On PostgreSQL only
(``postgres_only``: training, not storage, is the subject).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.support.ray_cluster import ray_cluster
from tests.support.runs import ENDLESS, TINY, create_run, progressed, run_app, wait_run
from tests.support.studies import new_study
from tests.support.web import ADMIN

pytestmark = [pytest.mark.ray, pytest.mark.training, pytest.mark.postgres_only]


@pytest.fixture(scope="module")
def ray_address() -> Iterator[str]:
    with ray_cluster() as address:
        yield address


def test_runs_execute_as_ray_tasks(settings, ray_address: str) -> None:
    with run_app(settings, ray_address=ray_address) as client:
        study_id = new_study(client)["id"]
        tiny = create_run(
            client,
            study_id=study_id,
            teacher="good",
            algo="bipars-em",
            timesteps=512,
            checkpoint_every=256,
            **TINY,
        )
        long = create_run(client, study_id=study_id, teacher="good", algo="ppo-shaped", **ENDLESS)
        done = wait_run(client, tiny)
        assert done["status"] == "succeeded" and done["executor"] == "ray", done
        checkpoints = client.get(f"/api/runs/{tiny}/checkpoints", headers=ADMIN).json()
        assert [c["checkpoint"] for c in checkpoints] == [256, 512]
        agent = client.get(f"/api/runs/{tiny}/agent-tree", headers=ADMIN).json()
        assert agent["judge"] == "agent:return@512"

        wait_run(client, long, progressed)
        client.post(f"/api/runs/{long}/cancel", headers=ADMIN)
        stopped = wait_run(client, long)
        assert stopped["status"] == "cancelled" and stopped["executor"] == "ray", stopped
        steps = client.get(f"/api/runs/{long}/checkpoints", headers=ADMIN).json()
        assert steps[-1]["checkpoint"] == stopped["progress"]["done"]
