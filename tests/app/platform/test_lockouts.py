"""Failed-login lockouts counted in the app's database (issue 45 §4), on SQLite and
PostgreSQL: one limit for every process and host, no database work for an address a process
knows is blocked, old failures pruned, and the window freeing.

Two ``uvicorn`` processes started as Compose starts the web service (one database, a port
each, as two hosts would be) share one limit: five failures on each lock the address out
of both.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from datetime import timedelta
from pathlib import Path

import httpx
import pytest
from sqlalchemy import Engine, event, func, insert, select

from app.db import make_engine, writing
from app.http.lockouts import DatabaseFailures
from app.http.ratelimit import FAILED_LOGINS_PER_MINUTE
from app.models import LoginFailure, utcnow
from tests.support.net import free_port
from tests.support.server import REPO, clean_env, wait_healthy
from tests.support.wait import wait_for
from tests.support.web import ADMIN, ADMIN_TOKEN

BAD = {"Authorization": "Bearer not-the-admin-token-and-no-invite-token"}


@pytest.fixture
def engine(backend_url: tuple[Path, str]) -> Iterator[Engine]:
    """The module's database, with no failure stored."""
    made = make_engine(backend_url[1])
    with made.connect() as conn, writing(conn):
        conn.execute(LoginFailure.__table__.delete())
    yield made
    made.dispose()


def _rows(engine: Engine) -> int:
    with engine.connect() as conn:
        return conn.scalar(select(func.count()).select_from(LoginFailure)) or 0


@contextmanager
def _statements(engine: Engine) -> Iterator[list[str]]:
    """Every SQL statement ``engine`` runs meanwhile."""
    seen: list[str] = []

    def record(_conn, _cursor, statement, *_args) -> None:
        seen.append(statement)

    event.listen(engine, "before_cursor_execute", record)
    try:
        yield seen
    finally:
        event.remove(engine, "before_cursor_execute", record)


def test_one_limit_for_every_process_then_no_database_work(engine: Engine) -> None:
    here, there = (DatabaseFailures(engine, FAILED_LOGINS_PER_MINUTE) for _ in range(2))
    for i in range(FAILED_LOGINS_PER_MINUTE):
        assert not (here if i % 2 else there).blocked("10.0.0.1")
        (here if i % 2 else there).failed("10.0.0.1")
    assert here.blocked("10.0.0.1") and there.blocked("10.0.0.1")
    assert not here.blocked("10.0.0.2")  # another address
    assert 30 <= here.retry_after_s("10.0.0.1") <= 60
    with _statements(engine) as seen:
        for _ in range(50):  # an attack from a blocked address
            assert here.blocked("10.0.0.1")
            here.failed("10.0.0.1")
            assert here.retry_after_s("10.0.0.1") >= 1
    assert seen == []
    assert _rows(engine) == FAILED_LOGINS_PER_MINUTE


def test_old_failures_are_pruned_and_the_window_frees(engine: Engine) -> None:
    long_ago = utcnow() - timedelta(minutes=5)
    with engine.connect() as conn, writing(conn):
        rows = [{"address": f"10.1.0.{i}", "at": long_ago} for i in range(20)]
        conn.execute(insert(LoginFailure), rows)
    failures = DatabaseFailures(engine, 2)
    failures.WINDOW = timedelta(seconds=1)
    assert not failures.blocked("10.1.0.1")  # old failures count for nothing
    failures.failed("10.2.0.1")
    assert _rows(engine) == 1  # the old ones are gone
    failures.failed("10.2.0.1")
    assert failures.blocked("10.2.0.1")
    # this process's "blocked until" expires with the window
    wait_for(lambda: not failures.blocked("10.2.0.1"), what="the window to free", timeout_s=10)


@contextmanager
def _web(backend_url: tuple[Path, str], log: Path) -> Iterator[str]:
    """One ``web`` service of docker-compose.yml (its command, with one worker and a port of
    its own) on the module's database; yields its base URL."""
    data_dir, url = backend_url
    env = clean_env(
        DATABASE_URL=url,
        ACV_DATA_DIR=str(data_dir),
        ACV_ADMIN_TOKEN=ADMIN_TOKEN,
        ACV_RUN_WORKER="false",
        ACV_FORWARDED_ALLOW_IPS="",
    )
    port = free_port()
    command = [
        *(sys.executable, "-m", "uvicorn", "--factory", "app.main:create_app"),
        *("--host", "127.0.0.1", "--port", str(port), "--workers", "1"),
        *("--timeout-graceful-shutdown", "10", "--no-proxy-headers"),
    ]
    with log.open("w") as output:
        proc = subprocess.Popen(command, cwd=REPO, env=env, stdout=output, stderr=output)
        base = f"http://127.0.0.1:{port}"
        try:
            wait_healthy(base, proc, timeout_s=180)
            yield base
        finally:
            proc.terminate()
            proc.wait(timeout=60)


def _get(base: str, headers: dict[str, str]) -> httpx.Response:
    with httpx.Client(timeout=30) as client:
        return client.get(f"{base}/api/studies", headers=headers)


@pytest.mark.process
def test_two_compose_web_processes_share_one_limit(
    backend_url: tuple[Path, str], engine: Engine, tmp_path: Path
) -> None:
    with ExitStack() as servers:
        bases = [servers.enter_context(_web(backend_url, tmp_path / f"web{i}.log")) for i in (0, 1)]
        for i in range(FAILED_LOGINS_PER_MINUTE):  # half on each process
            assert _get(bases[i % 2], BAD).status_code == 401
        for base in bases:
            refused = _get(base, BAD)
            assert refused.status_code == 429 and int(refused.headers["Retry-After"]) >= 1
            assert _get(base, ADMIN).status_code == 429  # even the right token, until it frees
    assert _rows(engine) == FAILED_LOGINS_PER_MINUTE
