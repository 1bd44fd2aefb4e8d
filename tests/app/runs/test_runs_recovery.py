"""Runs survive what happens to their workers: restarts, killed processes, racing claims.

- a queued run survives a restart; stopping the server leaves a running run ``interrupted``
  with a checkpoint, and resuming it continues from there;
- a run process (named ``acv-run-<id>``) that dies (SIGKILL) makes its run ``failed`` with
  the reason;
- a worker that dies (SIGKILL of ``acv worker``, started by its console script as a user
  would) stops its run processes, whose runs become ``interrupted``; at startup, running runs
  of vanished workers become ``interrupted``;
- two workers never take the same run; a run that fails reports its error.

Runs on SQLite and PostgreSQL.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from collections import Counter
from datetime import timedelta
from pathlib import Path

import pytest

from app.db import make_engine, make_sessions
from app.jobs import queue
from app.models import Run, utcnow
from engine.rl.logger import read_metrics
from tests.support.runs import (
    ENDLESS,
    TINY,
    create_run,
    get_run,
    progressed,
    run_app,
    wait_run,
)
from tests.support.studies import new_study
from tests.support.wait import wait_for
from tests.support.web import ADMIN

pytestmark = pytest.mark.training


@pytest.fixture(scope="module")
def study_id(settings) -> int:
    with run_app(settings, worker=False) as client:
        return new_study(client)["id"]


@pytest.fixture
def sessions(settings):
    engine = make_engine(settings.sqlalchemy_url)
    yield make_sessions(engine)
    engine.dispose()


def teacher_run(client, study_id: int, **body) -> int:
    return create_run(
        client, study_id=study_id, teacher="standing", algo="bipars-em", **{**ENDLESS, **body}
    )


def test_queued_survives_restart_and_interrupted_resumes(settings, study_id: int) -> None:
    with run_app(settings, worker=False) as client:
        run_id = teacher_run(client, study_id)
        dropped = teacher_run(client, study_id)
        cancelled = client.post(f"/api/runs/{dropped}/cancel", headers=ADMIN).json()
        assert cancelled["status"] == "cancelled"  # a queued run is cancelled at once
    with run_app(settings) as client:  # the queued run starts after the restart
        wait_run(client, run_id, progressed)
    with run_app(settings) as client:
        run = get_run(client, run_id)  # the server stopped: the run checkpointed and stopped
        assert run["status"] == "interrupted" and "resume" in run["error"], run
        stopped_at = run["progress"]["done"]
        checkpoints = client.get(f"/api/runs/{run_id}/checkpoints", headers=ADMIN).json()
        assert checkpoints[-1]["checkpoint"] == stopped_at
        assert get_run(client, dropped)["status"] == "cancelled"
        resumed = client.post(f"/api/runs/{run_id}/resume", headers=ADMIN)
        assert resumed.status_code == 202, resumed.text
        wait_run(client, run_id, lambda r: r["progress"]["done"] > stopped_at)
        client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN)
        assert wait_run(client, run_id)["status"] == "cancelled"
    steps = [r["timesteps"] for r in read_metrics(settings.data_dir / "runs" / str(run_id))]
    assert steps == list(range(128, steps[-1] + 1, 128))  # one row per update, no gap


def test_a_killed_run_process_fails_the_run(settings, study_id: int) -> None:
    with run_app(settings) as client:
        run_id = teacher_run(client, study_id)
        wait_run(client, run_id, progressed)
        pid = client.app.state.run_worker.executor.pid(run_id)
        assert Path(f"/proc/{pid}/comm").read_text() == f"acv-run-{run_id}\n"  # for pgrep, top
        os.kill(pid, signal.SIGKILL)
        run = wait_run(client, run_id)
        assert run["status"] == "failed" and "killed by SIGKILL" in run["error"], run
        resumed = client.post(f"/api/runs/{run_id}/resume", headers=ADMIN)
        assert resumed.status_code == 202  # from its last checkpoint
        client.post(f"/api/runs/{run_id}/cancel", headers=ADMIN)
        assert wait_run(client, run_id)["status"] == "cancelled"


def test_a_killed_worker_stops_its_runs(settings, study_id: int) -> None:
    with run_app(settings, worker=False) as client:
        run_id = teacher_run(client, study_id)
        env = {k: v for k, v in os.environ.items() if k != "ACV_RAY_ADDRESS"}
        env |= {
            "ACV_DATA_DIR": str(settings.data_dir),
            "DATABASE_URL": settings.database_url,
            "ACV_POLL_S": "0.1",
        }
        worker = subprocess.Popen(
            [str(Path(sys.executable).with_name("acv")), "worker"],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            wait_run(client, run_id, progressed)
        finally:
            worker.kill()
            worker.wait()
        run = wait_run(client, run_id)  # its process checkpoints and gives up the run
        assert run["status"] == "interrupted", run
        # The process logs its outcome after storing it: wait for the line.
        log = settings.data_dir / "runs" / str(run_id) / "process.log"
        wait_for(
            lambda: f"run {run_id}: interrupted" in log.read_text(),
            what=f"run {run_id}'s process to log its end",
        )


def _dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def test_runs_of_vanished_workers_are_interrupted_at_startup(
    settings, study_id: int, sessions
) -> None:
    with run_app(settings, worker=False) as client:
        ids = [teacher_run(client, study_id) for _ in range(3)]
    here, now = socket.gethostname(), utcnow()
    owners = {
        ids[0]: (f"{here}:{_dead_pid()}:dead", now),
        ids[1]: ("elsewhere:1:quiet", now - timedelta(seconds=queue.STALE_S + 5)),
        ids[2]: ("elsewhere:1:busy", now),
    }
    with sessions() as session:
        for run_id, (worker, beat) in owners.items():
            assert queue.update_if(
                session, (Run.id == run_id,), status="running", worker=worker, heartbeat_at=beat
            )
    with run_app(settings) as client:
        # One recovery pass marks both, one row after the other: wait for each.
        for gone in ids[:2]:
            wait_run(client, gone, lambda r: r["status"] == "interrupted")
        assert get_run(client, ids[2])["status"] == "running"  # alive elsewhere
        with sessions() as session:
            queue.update_if(session, (Run.id == ids[2],), status="failed")


def test_two_workers_never_take_the_same_run(settings, study_id: int, sessions) -> None:
    with run_app(settings, worker=False) as client:
        ids = [teacher_run(client, study_id) for _ in range(8)]
    claims: list[int] = []

    def claim_all(worker: str) -> None:
        with sessions() as session:
            while run_id := queue.claim_next(session, worker=worker, executor="test"):
                claims.append(run_id)

    threads = [threading.Thread(target=claim_all, args=(f"w{i}",)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert Counter(claims) == Counter(ids)  # each exactly once
    with sessions() as session:
        for run_id in ids:
            queue.update_if(session, (Run.id == run_id,), status="failed")


def test_a_failing_run_reports_its_error(settings, study_id: int) -> None:
    with run_app(settings, worker=False) as client:
        run_id = create_run(client, study_id=study_id, algo="ppo", timesteps=256, **TINY)
    taken = settings.data_dir / "runs" / str(run_id)
    taken.mkdir(parents=True)
    (taken / "config.json").write_text("{}")  # as if another run had used the directory
    with run_app(settings) as client:
        run = wait_run(client, run_id)
    assert run["status"] == "failed" and "already holds a run" in run["error"], run
