"""Labelling under load with a ``kill -9`` midway: of the server (on SQLite and PostgreSQL;
the reduced size of ``benchmarks/fault_load.py``, whose code this runs), and of the training
worker.

Every label that got a 2xx is stored with its acknowledged winner, no match has two labels,
every racing loser got 409, nothing answered 5xx, every participant finished the bracket
after the restart, and the killed worker's run is ``interrupted`` and resumable.
"""

from __future__ import annotations

import asyncio
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from tests.support.benchmarks import load_benchmark
from tests.support.postgres import BACKENDS
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.wait import wait_for

pytestmark = pytest.mark.process  # acv serve (and acv worker) under load, killed midway

REPO = Path(__file__).resolve().parents[3]
PARTICIPANTS, CANDIDATES = 8, 8
#: A PPO budget that would take hours: the run is stopped once it has shown progress.
ENDLESS_RUN = {
    "timesteps": 10_000_000,
    "n_envs": 1,
    "num_steps": 128,
    "num_minibatches": 4,
    "update_epochs": 2,
    "checkpoint_every": 256,
}


@pytest.mark.parametrize("backend", BACKENDS)
def test_labels_survive_kill_9_under_load(request, tmp_path: Path, backend: str) -> None:
    bench = load_benchmark("fault_load")
    config = bench.LoadConfig(
        participants=PARTICIPANTS,
        candidates=CANDIDATES,
        env_id="Hopper-v5",
        think_ms=30.0,
        race_share=0.3,
        kill_at=0.4,
        timeout_s=90.0,
    )
    url = request.getfixturevalue("postgres").create_database() if backend != "sqlite" else None
    figures = bench.run_backend(config, url, tmp_path, steady=False)
    expected = PARTICIPANTS * (CANDIDATES - 1)
    assert figures["kills"] == 1 and figures["finished"] == PARTICIPANTS, figures
    assert figures["unexpected"] == [], figures
    assert (figures["lost"], figures["duplicates"], figures["server_errors_5xx"]) == (0, 0, 0)
    # A label whose answer was cut off by the kill is stored but never acknowledged.
    assert figures["labels_acknowledged"] <= figures["labels_stored"] == expected
    assert figures["races"] > 0 and figures["race_losers_409"] == figures["races"]
    assert figures["conflicts_409"] >= figures["races"]


def _run(base: str, run_id: int) -> dict:
    return (
        httpx.get(
            f"{base}/api/runs/{run_id}",
            headers=load_benchmark("fault_load").ADMIN,
            timeout=HTTP_TIMEOUT_S,
        )
        .raise_for_status()
        .json()
    )


def _wait(base: str, run_id: int, until, timeout_s: float = 120.0) -> dict:
    return wait_for(lambda: _run(base, run_id), until, what=f"run {run_id}", timeout_s=timeout_s)


def _worker(env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", "from app.cli import main; main()", "worker"],
        cwd=REPO,
        env=env | {"ACV_POLL_S": "0.1"},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


@pytest.mark.training
def test_labels_and_a_run_survive_kill_9_of_the_worker(tmp_path: Path) -> None:
    """``acv worker`` is killed while it trains and participants label (SQLite: the run
    process and the server write to one database file): every label is stored, the run is
    marked ``interrupted``, and resumed by a new worker it continues from its checkpoint."""
    bench = load_benchmark("fault_load")
    admin = bench.ADMIN
    config = bench.LoadConfig(
        participants=PARTICIPANTS,
        candidates=CANDIDATES,
        env_id="Hopper-v5",
        think_ms=100.0,
        timeout_s=90.0,
    )
    server = bench.Server(tmp_path, None)
    server.env["ACV_RUN_WORKER"] = "false"
    server.start()
    workers = [_worker(server.env)]
    try:
        study_id, people = bench.prepare(server.base, config, PARTICIPANTS)
        body = {"study_id": study_id, "teacher": "standing", "algo": "bipars-em", **ENDLESS_RUN}
        run_id = (
            httpx.post(f"{server.base}/api/runs", headers=admin, json=body, timeout=HTTP_TIMEOUT_S)
            .raise_for_status()
            .json()["id"]
        )
        with ThreadPoolExecutor(1) as pool:
            load = pool.submit(
                asyncio.run, bench.run_load(None, server.base, [tok for _, tok in people], config)
            )
            before = _wait(server.base, run_id, lambda r: r["progress"]["done"] >= 256)
            workers[0].kill()  # kill -9, mid-run and mid-load
            _wait(server.base, run_id, lambda r: r["status"] == "interrupted")
            workers.append(_worker(server.env))
            httpx.post(
                f"{server.base}/api/runs/{run_id}/resume", headers=admin, timeout=HTTP_TIMEOUT_S
            ).raise_for_status()
            after = _wait(
                server.base,
                run_id,
                lambda r: (
                    r["status"] == "running" and r["progress"]["done"] > before["progress"]["done"]
                ),
            )
            tally = load.result()
        httpx.post(
            f"{server.base}/api/runs/{run_id}/cancel", headers=admin, timeout=HTTP_TIMEOUT_S
        ).raise_for_status()
    finally:
        for worker in workers:
            worker.kill()
            worker.wait()
        server.stop()
    stored = bench.stored_labels(
        f"sqlite:///{tmp_path / 'acv.sqlite3'}", [pid for pid, _ in people]
    )
    assert tally.finished == PARTICIPANTS and tally.server_errors == 0 and not tally.unexpected
    assert {m: [w] for m, w in tally.acked.items()} == stored
    assert len(stored) == PARTICIPANTS * (CANDIDATES - 1)
    assert after["progress"]["done"] >= 256  # from the checkpoint, not from scratch
