"""The web tier only reads checkpoint artefacts: a server process in which torch and MuJoCo
cannot be imported serves a run's compare page, its checkpoint report and its conformance curve.

A run trains first (in-process app, its own worker: torch is there), so that its checkpoint
artefacts are stored. Then ``acv serve`` starts in a subprocess on the same database and data
dir, without a run worker, with a ``sitecustomize`` that makes ``import torch`` and
``import mujoco`` raise ImportError. Every answer must be a 200 with the stored numbers.
On PostgreSQL only.
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from app.settings import Settings
from tests.support.runs import TINY, create_run, finished_participant, run_app, wait_run
from tests.support.server import HTTP_TIMEOUT_S, wait_healthy
from tests.support.studies import new_study
from tests.support.web import ADMIN, ADMIN_TOKEN

pytestmark = pytest.mark.postgres_only  # serving without torch is the subject, not storage

REPO = Path(__file__).resolve().parents[3]
BLOCKER = '''
import sys


class _NoHeavyImports:
    """The web process must not need these: importing them fails."""

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "mujoco"):
            raise ImportError(f"{name} is blocked in this web process")
        return None


sys.meta_path.insert(0, _NoHeavyImports())
'''


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def judged_run(settings: Settings) -> dict:
    """A finished ``bipars-em`` run with advice (artefacts stored by its executor)."""
    with run_app(settings) as client:
        study = new_study(client)
        participant = finished_participant(client, study["id"])
        run_id = create_run(
            client,
            study_id=study["id"],
            participant_id=participant,
            algo="bipars-em",
            timesteps=512,
            checkpoint_every=256,
            **TINY,
        )
        run = wait_run(client, run_id)
        assert run["status"] == "succeeded", run
        run["curve"] = client.get(f"/api/runs/{run_id}/conformance-curve", headers=ADMIN).json()
    return run


@pytest.fixture(scope="module")
def bare_server(
    settings: Settings, judged_run: dict, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[str]:
    """``acv serve`` with torch and MuJoCo unimportable; yields its base URL."""
    site = tmp_path_factory.mktemp("no-torch-site")
    (site / "sitecustomize.py").write_text(BLOCKER)
    env = {k: v for k, v in os.environ.items() if k != "ACV_RAY_ADDRESS"}
    env |= {
        "PYTHONPATH": os.pathsep.join([str(site), str(REPO)]),
        "ACV_DATA_DIR": str(settings.data_dir),
        "DATABASE_URL": settings.sqlalchemy_url,
        "ACV_ADMIN_TOKEN": ADMIN_TOKEN,
        "ACV_RUN_WORKER": "false",
    }
    port, log = _free_port(), settings.data_dir / "bare-server.log"
    with log.open("w") as out:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-c",
                "from app.cli import main; main()",
                "serve",
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--no-access-log",
            ],
            cwd=REPO,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
        base = f"http://127.0.0.1:{port}"
        try:
            _wait_healthy(proc, base, log)
            yield base
        finally:
            proc.terminate()
            proc.wait(timeout=60)


def _wait_healthy(proc: subprocess.Popen, base: str, log: Path) -> None:
    try:
        wait_healthy(base, proc)
    except (AssertionError, pytest.fail.Exception):
        pytest.fail(f"the server did not start:\n{log.read_text()}")


def test_the_blocker_blocks(tmp_path: Path) -> None:
    (tmp_path / "sitecustomize.py").write_text(BLOCKER)
    env = os.environ | {"PYTHONPATH": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", "import torch"], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 1 and "torch is blocked" in done.stderr


def test_compare_page_and_curve_without_torch_or_mujoco(bare_server: str, judged_run: dict) -> None:
    run_id = judged_run["id"]
    with httpx.Client(base_url=bare_server, timeout=HTTP_TIMEOUT_S) as web:
        form = web.get("/login").text
        token = re.search(r'name="csrf_token" value="([^"]+)"', form).group(1)
        web.post("/login", data={"csrf_token": token, "token": ADMIN_TOKEN, "next": "/"})
        page = web.get(f"/runs/{run_id}/compare?judge=behaviour")
        assert page.status_code == 200 and 'id="candidates"' in page.text
        assert 'data-checkpoints="256,512"' in page.text
        api = {"headers": ADMIN}
        curve = web.get(f"/api/runs/{run_id}/conformance-curve", **api)
        assert curve.status_code == 200 and curve.json() == judged_run["curve"]
        report = web.get(f"/api/runs/{run_id}/checkpoint-report?judge=behaviour", **api)
        assert report.status_code == 200 and report.json()["checkpoint"] == 512
        assert report.json()["judge"] == "behaviour" and report.json()["candidates"]
        tree = web.get(f"/api/runs/{run_id}/agent-tree?checkpoint=256&judge=behaviour", **api)
        assert tree.status_code == 200 and tree.json()["judge"] == "agent:behaviour@256"


def test_the_run_is_served_from_rows_with_its_folder_gone(
    bare_server: str, judged_run: dict, settings: Settings
) -> None:
    """Issue 26 §4: the web reads a run's state from the database, never its folder (which
    may be on another machine): with the folder moved away, its metrics, its checkpoints and
    its HTML report still answer, from a server that cannot import torch or MuJoCo."""
    run_id = judged_run["id"]
    folder = settings.data_dir / "runs" / str(run_id)
    away = folder.with_name(f"{run_id}-away")
    folder.rename(away)
    try:
        with httpx.Client(base_url=bare_server, timeout=HTTP_TIMEOUT_S, headers=ADMIN) as api:
            metrics = api.get(f"/api/runs/{run_id}/metrics").json()
            checkpoints = api.get(f"/api/runs/{run_id}/checkpoints").json()
            report = api.get(f"/api/runs/{run_id}/report.html")
        assert [m["timesteps"] for m in metrics] == [128, 256, 384, 512]
        assert [c["checkpoint"] for c in checkpoints] == [256, 512]
        assert report.status_code == 200 and "Agent Preference Tree" in report.text
    finally:
        away.rename(folder)
