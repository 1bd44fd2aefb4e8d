"""App-test fixtures: every API test runs on SQLite AND on a real PostgreSQL server.

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

import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.db import upgrade
from app.jobs.settings import JobSettings
from app.main import create_app
from app.settings import Settings
from tests.support.postgres import BACKENDS, PostgresCluster, PostgresMissing
from tests.support.wait import wait_for
from tests.support.web import ADMIN, ADMIN_TOKEN

__all__ = ["ADMIN", "ADMIN_TOKEN", "BACKENDS", "Player", "new_study", "wait_ready"]


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


@pytest.fixture(scope="module", params=BACKENDS)
def backend_url(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, str]:
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
    """The app on this module's database, lifespan running. Its worker never backfills by
    itself (a module's tests decide when checkpoints get judged; see ``test_backfill_worker``)."""
    app = create_app(settings)
    app.state.job_settings = JobSettings(backfill_s=0)
    with TestClient(app) as test_client:
        yield test_client


def wait_ready(client: TestClient, study_id: int, timeout_s: float = 60.0) -> dict[str, Any]:
    """Poll a study until it leaves ``preparing``; returns its JSON."""
    return wait_for(
        lambda: client.get(f"/api/studies/{study_id}", headers=ADMIN).json(),
        lambda body: body["status"] != "preparing",
        what=f"study {study_id} to leave preparing",
        timeout_s=timeout_s,
        every_s=0.05,
    )


def new_study(client: TestClient, **overrides: Any) -> dict[str, Any]:
    """Create a small Hopper study and wait until it is prepared."""
    body = {
        "name": "test study",
        "env_id": "Hopper-v5",
        "n_candidates": 5,
        "p": 0.9,
        "seed": 3,
        "sampling": "uniform",
        "instructions": "Pick the taller one.",
    }
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
        return self.client.post(
            f"/api/matches/{match_id}/label", headers=self.headers, json={"winner": winner, **extra}
        )

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
        response = client.post(
            f"/api/studies/{study_id or study['id']}/participants", headers=ADMIN
        )
        assert response.status_code == 201, response.text
        body = response.json()
        return Player(client, body["id"], body["token"], body["invite_url"])

    return _invite


@pytest.hookimpl(tryfirst=True)  # before `-m` selects by marker
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """A test that drives the browser is a ``browser`` test, whether its module says so or not."""
    for item in items:
        if "browser" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
