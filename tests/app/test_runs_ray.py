"""The ``ray`` executor against a real Ray instance that the test starts on 127.0.0.1.

``ray start --head --block`` runs in its own session with its own temp dir; the app, given
``ACV_RAY_ADDRESS`` (here ``JobSettings(ray_address=...)``), runs every claimed run as a Ray
task that reports to the database: a tiny run succeeds with its checkpoints and agent tree,
and a long one stops with a checkpoint when it is cancelled. Runs on SQLite and PostgreSQL.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support.net import free_port, listening
from tests.support.runs import ENDLESS, TINY, create_run, progressed, run_app, wait_run
from tests.support.studies import new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN

pytestmark = [pytest.mark.ray, pytest.mark.training]
RAY = Path(sys.executable).with_name("ray")


def _head_up(head: subprocess.Popen, port: int) -> bool:
    assert head.poll() is None, "ray start exited"
    return listening(port)


@pytest.fixture(scope="module")
def ray_address() -> Iterator[str]:
    """A one-node Ray cluster with 2 CPUs on 127.0.0.1, stopped (with all its processes)
    after the module."""
    port, temp = free_port(), tempfile.mkdtemp(prefix="acvray")  # sockets need a short path
    # One setting for the head, its workers and the app's driver (this process): a token left
    # in ~/.ray by another cluster would otherwise switch token authentication on for some.
    saved = os.environ.get("RAY_AUTH_MODE")
    os.environ["RAY_AUTH_MODE"] = "disabled"
    env = os.environ | {"RAY_USAGE_STATS_ENABLED": "0"}
    head = subprocess.Popen(
        [
            str(RAY),
            "start",
            "--head",
            "--block",
            "--node-ip-address=127.0.0.1",
            f"--port={port}",
            "--num-cpus=2",
            "--include-dashboard=false",
            f"--dashboard-port={free_port()}",
            f"--ray-client-server-port={free_port()}",
            "--disable-usage-stats",
            f"--temp-dir={temp}",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        wait_for(lambda: _head_up(head, port), what="Ray to start", timeout_s=90, every_s=0.2)
        yield f"127.0.0.1:{port}"
    finally:
        os.killpg(head.pid, signal.SIGKILL)  # the head's session: GCS, raylet, workers
        head.wait()
        shutil.rmtree(temp, ignore_errors=True)
        if saved is None:
            os.environ.pop("RAY_AUTH_MODE", None)
        else:
            os.environ["RAY_AUTH_MODE"] = saved


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
