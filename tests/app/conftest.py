"""App-test fixtures: every API test runs on SQLite AND on a real PostgreSQL server.

Isolation: the services commit their own writes and study preparation runs on a background
thread with its own connections, so a per-test rolled-back transaction cannot hold them.
Instead each test module gets a fresh database per backend, built by ``alembic upgrade
head`` (SQLite: a new file; PostgreSQL: a new database on a throwaway cluster), and each test
invites its own participants, so tests never see each other's labels.

PostgreSQL is Debian's ``postgresql`` package (``make test`` installs it): a session fixture
runs ``initdb`` in a temporary directory and starts the server on 127.0.0.1 on a free port,
as the ``postgres`` user when we are root. Missing PostgreSQL is an error, never a skip.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import psycopg
import pytest
from fastapi.testclient import TestClient

from app.db import upgrade
from app.main import create_app
from app.settings import Settings

ADMIN_TOKEN = "test-admin-token-0123456789abcdefghij"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
BACKENDS = ("sqlite", "postgresql")


def _pg_bindir() -> Path:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"),
                   key=lambda p: int(Path(p).parts[-3]))
    initdb = found[-1] if found else shutil.which("initdb")
    if initdb is None:
        pytest.fail("PostgreSQL is not installed: `make test` installs Debian's postgresql "
                    "(apt-get install -y postgresql)", pytrace=False)
    return Path(initdb).parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresCluster:
    """A throwaway PostgreSQL cluster in a temporary directory, on 127.0.0.1."""

    def __init__(self) -> None:
        self.bindir = _pg_bindir()
        self.root = Path(tempfile.mkdtemp(prefix="acv-pg-"))
        self.user = "postgres" if os.geteuid() == 0 else None  # initdb refuses root
        if self.user:
            entry = pwd.getpwnam(self.user)
            os.chown(self.root, entry.pw_uid, entry.pw_gid)
        self.port = _free_port()

    def _run(self, *args: str) -> None:
        subprocess.run([str(self.bindir / args[0]), *args[1:]], check=True, user=self.user,
                       capture_output=True, cwd=self.root)

    def start(self) -> None:
        data = self.root / "data"
        self._run("initdb", "-D", str(data), "-U", "postgres", "--auth=trust", "--no-sync",
                  "--no-locale", "-E", "UTF8")
        self._run("pg_ctl", "-D", str(data), "-l", str(self.root / "log"), "-w", "-o",
                  f"-h 127.0.0.1 -p {self.port} -k {self.root} -F", "start")

    def stop(self) -> None:
        try:
            self._run("pg_ctl", "-D", str(self.root / "data"), "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)

    def url(self, database: str) -> str:
        return f"postgresql://postgres@127.0.0.1:{self.port}/{database}"

    def create_database(self) -> str:
        """A new empty database; returns its URL."""
        name = f"acv_{uuid.uuid4().hex[:12]}"
        with psycopg.connect(self.url("postgres"), autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresCluster]:
    cluster = PostgresCluster()
    try:
        cluster.start()
    except subprocess.CalledProcessError as exc:
        log = cluster.root / "log"
        cluster.stop()
        pytest.fail(f"could not start PostgreSQL: {exc.stderr.decode()[-2000:]}"
                    f"{log.read_text()[-2000:] if log.exists() else ''}", pytrace=False)
    yield cluster
    cluster.stop()


@pytest.fixture(scope="module", params=BACKENDS)
def backend_url(request: pytest.FixtureRequest,
                tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``(data dir, database URL)`` of a fresh database built by ``alembic upgrade head``."""
    data_dir = tmp_path_factory.mktemp(f"acv-{request.param}")
    if request.param == "sqlite":
        url = f"sqlite:///{data_dir / 'acv.sqlite3'}"
    else:
        url = request.getfixturevalue("postgres").create_database()
    upgrade(url)
    return data_dir, url


@pytest.fixture(scope="module")
def settings(backend_url: tuple[Path, str]) -> Settings:
    data_dir, url = backend_url
    return Settings(data_dir=data_dir, database_url=url, admin_token=ADMIN_TOKEN)


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    """The app on this module's database, lifespan running."""
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def wait_ready(client: TestClient, study_id: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """Poll a study until it leaves ``preparing``; returns its JSON."""
    deadline = time.monotonic() + timeout_s
    while (body := client.get(f"/api/studies/{study_id}", headers=ADMIN).json())[
            "status"] == "preparing":
        assert time.monotonic() < deadline, f"study {study_id} still preparing"
        time.sleep(0.05)
    return body


def new_study(client: TestClient, **overrides: Any) -> dict[str, Any]:
    """Create a small Hopper study and wait until it is prepared."""
    body = {"name": "test study", "env_id": "Hopper-v5", "n_candidates": 5, "p": 0.9,
            "seed": 3, "sampling": "uniform", "instructions": "Pick the taller one."}
    response = client.post("/api/studies", json=body | overrides, headers=ADMIN)
    assert response.status_code == 201, response.text
    return wait_ready(client, response.json()["id"])


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


@dataclass
class Player:
    """A participant driving the REST API with their invite token."""

    client: TestClient
    id: int
    token: str
    invite_url: str

    @property
    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"}

    def next_match(self) -> dict[str, Any] | None:
        response = self.client.get("/api/participants/me/next-match", headers=self.headers)
        assert response.status_code in (200, 204), response.text
        return response.json() if response.status_code == 200 else None

    def label(self, match_id: int, winner: int, **extra: Any):
        return self.client.post(f"/api/matches/{match_id}/label", headers=self.headers,
                                json={"winner": winner, **extra})

    def play(self, choose: Callable[[dict[str, Any]], int] | None = None) -> int:
        """Label every match (``choose`` picks the winner; default the ``a`` side)."""
        sent = 0
        while (match := self.next_match()) is not None:
            winner = choose(match) if choose else match["a"]["candidate_id"]
            assert self.label(match["match_id"], winner).status_code == 201
            sent += 1
        return sent


@pytest.fixture
def invite(client: TestClient, study: dict[str, Any]) -> Callable[..., Player]:
    """Invite a fresh participant to ``study`` (or another study id)."""

    def _invite(study_id: int | None = None) -> Player:
        response = client.post(f"/api/studies/{study_id or study['id']}/participants",
                               headers=ADMIN)
        assert response.status_code == 201, response.text
        body = response.json()
        return Player(client, body["id"], body["token"], body["invite_url"])

    return _invite
