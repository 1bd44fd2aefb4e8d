"""App-test fixtures: API tests run on SQLite AND on a real PostgreSQL server.

A module whose subject is not storage (training, rendering, pages, evaluations, the sweeps of
every route's validation and authorization) is marked ``postgres_only`` and runs on
PostgreSQL alone, the stricter backend; modules about what storage does (labels, limits under
concurrency, leases, migrations, exports, SQLite's own integer limits) run on both.

Isolation: the services commit their own writes and study preparation runs on a background
thread with its own connections, so a per-test rolled-back transaction cannot hold them.
Instead each test module gets a fresh database per backend, built by ``alembic upgrade
head`` (SQLite: a new file; PostgreSQL: a new database on a throwaway cluster), and each test
invites its own participants, so tests never see each other's labels.

PostgreSQL is Debian's ``postgresql`` package (``make test`` installs it): a session fixture
runs ``initdb`` in a temporary directory and starts the server on 127.0.0.1 on a free port,
as the ``postgres`` user when we are root. Missing PostgreSQL is an error, never a skip.
The PostgreSQL parametrisations carry the ``postgres`` marker (``-m "not postgres"`` leaves
them out); the cluster code is in ``tests/support/postgres.py``.
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import closing
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from playwright.sync_api import Browser, sync_playwright

from app.db import upgrade
from app.jobs.settings import JobSettings
from app.main import create_app
from app.settings import Settings
from tests.support.browser import ADMIN_TOKEN as SERVER_ADMIN_TOKEN
from tests.support.browser import CHROMIUM, CHROMIUM_ARGS, SCREENS_COPY
from tests.support.postgres import BACKENDS, PostgresCluster, PostgresMissing
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.studies import Player, new_study
from tests.support.web import ADMIN, ADMIN_TOKEN


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresCluster]:
    try:
        cluster = PostgresCluster()
    except PostgresMissing as exc:
        pytest.fail(str(exc), pytrace=False)
    try:
        cluster.start()
    except subprocess.CalledProcessError as exc:
        log = cluster.root / "log"
        cluster.stop()
        pytest.fail(
            f"could not start PostgreSQL: {exc.stderr.decode()[-2000:]}"
            f"{log.read_text()[-2000:] if log.exists() else ''}",
            pytrace=False,
        )
    yield cluster
    cluster.stop()


@pytest.fixture(scope="session")
def sqlite_at_head(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite database built once by ``alembic upgrade head``, for modules to copy."""
    path = tmp_path_factory.mktemp("acv-sqlite-head") / "acv.sqlite3"
    upgrade(f"sqlite:///{path}")
    return path


@pytest.fixture(scope="module", params=BACKENDS)
def backend_url(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, str]:
    """``(data dir, database URL)`` of a fresh database at the migrations' head: a copy of one
    that ``alembic upgrade head`` built this session (``tests/app/platform/test_migrations.py`` runs
    the revisions themselves)."""
    data_dir = tmp_path_factory.mktemp(f"acv-{request.param}")
    if request.param == "sqlite":
        path = data_dir / "acv.sqlite3"
        # The backup API, not a file copy: it reads a consistent database whatever the WAL holds.
        head_path = request.getfixturevalue("sqlite_at_head")
        with closing(sqlite3.connect(head_path)) as head, closing(sqlite3.connect(path)) as copy:
            head.backup(copy)
        return data_dir, f"sqlite:///{path}"
    return data_dir, request.getfixturevalue("postgres").database_at_head()


@pytest.fixture(scope="module")
def settings(backend_url: tuple[Path, str]) -> Settings:
    """The app's settings; webhooks may point at 127.0.0.1 only (tests send no traffic
    elsewhere, and never ask DNS for a name)."""
    data_dir, url = backend_url
    return Settings(
        data_dir=data_dir, database_url=url, admin_token=ADMIN_TOKEN, webhook_targets="loopback"
    )


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    """The app on this module's database, lifespan running. Its worker never backfills by
    itself (a module's tests decide when checkpoints get judged; see ``test_backfill_worker``)."""
    app = create_app(settings)
    app.state.job_settings = JobSettings(backfill_s=0)
    with TestClient(app) as test_client:
        yield test_client


@pytest.fixture(scope="session")
def admin() -> dict[str, str]:
    """Researcher headers."""
    return dict(ADMIN)


@pytest.fixture(scope="module")
def make_study(client: TestClient) -> Callable[..., dict[str, Any]]:
    """Create a small study (keyword overrides of the body) and wait until prepared."""
    return lambda **overrides: new_study(client, **overrides)


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    """A ready 5-candidate study (so the first round has three byes)."""
    ready = new_study(client)
    assert ready["status"] == "ready", ready
    return ready


@pytest.fixture
def invite(client: TestClient, study: dict[str, Any]) -> Callable[..., Player]:
    """Invite a fresh participant to ``study`` (or another study id)."""

    def _invite(study_id: int | None = None) -> Player:
        response = client.post(
            f"/api/studies/{study_id or study['id']}/participants", headers=ADMIN
        )
        assert response.status_code == 201, response.text
        body = response.json()
        return Player(client, body["id"], body["token"], body["invite_url"])

    return _invite


@pytest.hookimpl(tryfirst=True)  # before `-m` selects by marker
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """A test that drives the browser is a ``browser`` test, whether its module says so or not.

    A ``postgres_only`` test (storage is not its subject, and each of its runs costs seconds:
    training, rendering, a server) leaves out its ``[sqlite]`` run; PostgreSQL is the stricter
    backend, and the storage these tests touch runs on both in the modules about storage.
    """
    for item in items:
        if "browser" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
    left_out = [item for item in items if _sqlite_run_of_postgres_only(item)]
    if left_out:
        config.hook.pytest_deselected(items=left_out)
        gone = set(left_out)
        items[:] = [item for item in items if item not in gone]


def _sqlite_run_of_postgres_only(item: pytest.Item) -> bool:
    callspec = getattr(item, "callspec", None)
    return (
        item.get_closest_marker("postgres_only") is not None
        and callspec is not None
        and callspec.params.get("backend_url") == "sqlite"
    )


# --- browser tests: acv serve in a subprocess, Debian's Chromium -----------------------------


@pytest.fixture(scope="module")
def api(server: tuple[str, Path]) -> Iterator[httpx.Client]:
    """A researcher's REST client on this module's ``acv serve``."""
    base, _ = server
    admin = {"Authorization": f"Bearer {SERVER_ADMIN_TOKEN}"}
    with httpx.Client(base_url=base, headers=admin, timeout=HTTP_TIMEOUT_S) as client:
        yield client


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """``acv serve`` on a free port; yields ``(base URL, file with its output and logs)``."""
    data_dir = tmp_path_factory.mktemp("acv-browser-data")
    log = data_dir / "server.log"  # one per server: tests find the data dir as its folder
    env = clean_env(
        ACV_DATA_DIR=str(data_dir),
        ACV_ADMIN_TOKEN=SERVER_ADMIN_TOKEN,
        ACV_WEBHOOK_TARGETS="loopback",
    )
    with acv_serve(env, log) as base:
        yield base, log


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    """Debian's Chromium, headless; never a downloaded browser."""
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture
def screens(tmp_path: Path) -> Iterator[Path]:
    """The screenshots folder; copied to ``/tmp/acv_screens`` afterwards."""
    folder = tmp_path / "screens"
    folder.mkdir()
    yield folder
    SCREENS_COPY.mkdir(parents=True, exist_ok=True)
    for shot in folder.glob("*.png"):
        shutil.copy(shot, SCREENS_COPY / shot.name)


class _Done(BaseHTTPRequestHandler):
    """The crowd platform's completion page, as far as this test needs it."""

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        body = b"<!doctype html><title>Completed</title><h1>Submission complete</h1>"
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *_args) -> None:
        pass


@pytest.fixture(scope="module")
def platform() -> Iterator[str]:
    """A local HTTP server standing in for the platform's completion URL."""
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), _Done)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
