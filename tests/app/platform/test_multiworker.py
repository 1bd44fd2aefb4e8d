"""``acv serve --workers 2``: two server processes on one socket and one database.

Labels go through both processes (each connection is accepted by one of them; the access
log names the process), the same label sent twice at once is stored once, every
acknowledged label is stored, the failed-login limit counts across processes, and the
training-run worker runs exactly once, in the supervisor. On SQLite and PostgreSQL.
"""

from __future__ import annotations

import csv
import io
import os
import re
import signal
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from app.http.ratelimit import FAILED_LOGINS_PER_MINUTE
from tests.support.net import free_port
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.wait import wait_for
from tests.support.web import ADMIN, ADMIN_TOKEN

pytestmark = pytest.mark.process

REPO = Path(__file__).resolve().parents[3]
START_TIMEOUT_S = 180.0
#: Fresh connections tried at most before both processes must have served a label.
MAX_CONNECTIONS = 400
LABEL_LINE = re.compile(r"\[(\d+)\] 127\.0\.0\.1:\d+ - \"POST /api/matches/\d+/label")


class Served:
    """``acv serve --workers 2`` in a subprocess, its output in a log file."""

    def __init__(self, data_dir: Path, database_url: str) -> None:
        self.port, self.log = free_port(), data_dir / "serve.log"
        self.base = f"http://127.0.0.1:{self.port}"
        env = {k: v for k, v in os.environ.items() if not k.startswith("ACV_")}
        env |= {
            "ACV_DATA_DIR": str(data_dir),
            "DATABASE_URL": database_url,
            "ACV_ADMIN_TOKEN": ADMIN_TOKEN,
            "PYTHONPATH": str(REPO),
        }
        with self.log.open("w") as out:
            self.proc = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "app.cli",
                    "serve",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(self.port),
                    "--workers",
                    "2",
                ],
                cwd=REPO,
                env=env,
                stdout=out,
                stderr=subprocess.STDOUT,
            )

    def text(self) -> str:
        return self.log.read_text()

    def wait_started(self) -> None:
        """Until both server processes have started and ``/healthz`` answers."""
        wait_for(
            self._both_started, what="both server processes to start", timeout_s=START_TIMEOUT_S
        )
        assert httpx.get(f"{self.base}/healthz", timeout=HTTP_TIMEOUT_S).status_code == 200

    def _both_started(self) -> bool:
        assert self.proc.poll() is None, self.text()[-3000:]
        return self.text().count("Application startup complete.") >= 2

    def server_pids(self) -> set[int]:
        return {int(p) for p in re.findall(r"Started server process \[(\d+)\]", self.text())}

    def label_pids(self) -> set[int]:
        return {int(p) for p in LABEL_LINE.findall(self.text())}

    def stop(self) -> int:
        """SIGTERM, as a service manager would; returns the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=60)


@pytest.fixture(scope="module")
def served(backend_url: tuple[Path, str]) -> Iterator[Served]:
    data_dir, url = backend_url
    server = Served(data_dir, url)
    try:
        server.wait_started()
        yield server
    finally:
        server.stop()


def _call(method: str, url: str, **kwargs) -> httpx.Response:
    """One request on a fresh connection (either process may accept it)."""
    with httpx.Client(timeout=30) as client:
        return client.request(method, url, **kwargs)


def _ready_study(base: str) -> int:
    body = {
        "name": "two workers",
        "env_id": "Hopper-v5",
        "n_candidates": 8,
        "p": 0.9,
        "seed": 4,
        "sampling": "uniform",
        "instructions": "",
    }
    study_id = _call("POST", f"{base}/api/studies", json=body, headers=ADMIN).json()["id"]
    status = wait_for(
        lambda: _call("GET", f"{base}/api/studies/{study_id}", headers=ADMIN).json()["status"],
        lambda got: got != "preparing",
        what=f"study {study_id}",
        timeout_s=120,
    )
    assert status == "ready"
    return study_id


def _invite(base: str, study_id: int, count: int) -> list[str]:
    people = _call(
        "POST",
        f"{base}/api/studies/{study_id}/participants/batch",
        headers=ADMIN,
        json={"count": count},
    )
    assert people.status_code == 201, people.text
    return [p["token"] for p in people.json()]


def _play(base: str, token: str, served: Served, acked: dict[int, int]) -> None:
    """Play a whole bracket, every decision sent twice at once on two fresh connections."""
    headers = {"Authorization": f"Bearer {token}"}
    match = _call("GET", f"{base}/api/participants/me/next-match", headers=headers).json()
    with ThreadPoolExecutor(2) as pool:
        while match is not None:
            winner, url = (
                match["a"]["candidate_id"],
                f"{base}/api/matches/{match['match_id']}/label",
            )
            sent = [
                pool.submit(_call, "POST", url, headers=headers, json={"winner": winner})
                for _ in range(2)
            ]
            answers = [future.result() for future in sent]
            assert sorted(r.status_code for r in answers) == [200, 201], [r.text for r in answers]
            acked[match["match_id"]] = winner
            assert answers[0].json()["next"] == answers[1].json()["next"]
            match = answers[0].json()["next"]


def test_labels_through_both_processes_stored_once(served: Served) -> None:
    base = served.base
    study_id = _ready_study(base)
    tokens = iter(_invite(base, study_id, 60))
    acked: dict[int, int] = {}
    # Each decision opens two connections: play until both processes have served labels.
    while len(served.label_pids()) < 2:
        assert len(acked) * 2 < MAX_CONNECTIONS, served.text()[-3000:]
        _play(base, next(tokens), served, acked)  # (a log line late by a bracket is fine)
    assert served.label_pids() <= served.server_pids() and len(served.server_pids()) == 2
    rows = list(
        csv.DictReader(
            io.StringIO(
                _call("GET", f"{base}/api/studies/{study_id}/labels.csv", headers=ADMIN).text
            )
        )
    )
    stored = {int(r["match_id"]): int(r["winner"]) for r in rows}
    assert Counter(r["match_id"] for r in rows).most_common(1)[0][1] == 1  # no duplicate
    assert stored == acked


def test_run_worker_runs_once_in_the_supervisor(served: Served) -> None:
    # The supervisor's worker thread logs its start while the server processes start.
    started = wait_for(
        lambda: re.findall(r"\[(\d+)\] worker \S+:(\d+):\w+ \(local executor", served.text()),
        what="the run worker's start line",
    )
    supervisor = re.findall(r"Started parent process \[(\d+)\]", served.text())
    assert len(started) == 1 and len(supervisor) == 1, served.text()[-3000:]
    logged_by, worker_pid = started[0]
    assert logged_by == worker_pid == supervisor[0] == str(served.proc.pid)
    assert int(worker_pid) not in served.server_pids()


def test_failed_logins_are_counted_across_processes(served: Served) -> None:
    bad = {"Authorization": "Bearer not-the-admin-token-and-no-invite-token"}
    for _ in range(FAILED_LOGINS_PER_MINUTE):
        assert _call("GET", f"{served.base}/api/studies", headers=bad).status_code == 401
    refused = _call("GET", f"{served.base}/api/studies", headers=bad)
    assert refused.status_code == 429 and int(refused.headers["Retry-After"]) >= 1
    assert _call("GET", f"{served.base}/api/studies", headers=ADMIN).status_code == 429


def test_sigterm_stops_every_process(served: Served) -> None:
    """(Last in this module: it stops the module's server.)"""
    pids = served.server_pids()
    assert served.stop() == 0, served.text()[-3000:]
    for pid in pids:  # the server processes are gone (reaped by the supervisor)
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
    assert "Finished server process" in served.text()
