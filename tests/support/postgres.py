"""A throwaway PostgreSQL cluster (Debian's ``postgresql`` package) on 127.0.0.1.

The app tests run every API test on it as well as on SQLite (``tests/app/conftest.py``), and
``benchmarks/fault_load.py`` uses it for its PostgreSQL figures.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import subprocess
import tempfile
import uuid
from pathlib import Path

import psycopg
import pytest

from app.db import upgrade
from tests.support.net import free_port

#: The database backends a test runs on; the PostgreSQL one is marked ``postgres`` (its tier).
BACKENDS = (
    pytest.param("sqlite", id="sqlite"),
    pytest.param("postgresql", id="postgresql", marks=pytest.mark.postgres),
)


class PostgresMissing(RuntimeError):
    """PostgreSQL's server programs are not installed."""


def empty_database(request: pytest.FixtureRequest, folder: Path, backend: str) -> str:
    """The URL of a new empty database: a SQLite file in ``folder``, or a PostgreSQL database
    on the session's server (the ``postgres`` fixture, started on first use)."""
    if backend == "sqlite":
        return f"sqlite:///{folder / 'acv.sqlite3'}"
    return str(request.getfixturevalue("postgres").create_database())


def pg_bindir() -> Path:
    """The newest installed PostgreSQL's ``bin`` directory (with ``initdb`` and ``pg_ctl``)."""
    found = sorted(
        glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: int(Path(p).parts[-3])
    )
    initdb = found[-1] if found else shutil.which("initdb")
    if initdb is None:
        raise PostgresMissing(
            "PostgreSQL is not installed: `make test` installs Debian's "
            "postgresql (apt-get install -y postgresql)"
        )
    return Path(initdb).parent


class PostgresCluster:
    """A throwaway PostgreSQL cluster in a temporary directory, on 127.0.0.1."""

    def __init__(self) -> None:
        self.bindir = pg_bindir()
        self.root = Path(tempfile.mkdtemp(prefix="acv-pg-"))
        self.user = "postgres" if os.geteuid() == 0 else None  # initdb refuses root
        if self.user:
            entry = pwd.getpwnam(self.user)
            os.chown(self.root, entry.pw_uid, entry.pw_gid)
        self.port = free_port()
        self._head: str | None = None

    def _run(self, *args: str) -> None:
        subprocess.run(
            [str(self.bindir / args[0]), *args[1:]],
            check=True,
            user=self.user,
            capture_output=True,
            cwd=self.root,
        )

    def start(self) -> None:
        data = self.root / "data"
        self._run(
            "initdb",
            "-D",
            str(data),
            "-U",
            "postgres",
            "--auth=trust",
            "--no-sync",
            "--no-locale",
            "-E",
            "UTF8",
        )
        self._run(
            "pg_ctl",
            "-D",
            str(data),
            "-l",
            str(self.root / "log"),
            "-w",
            "-o",
            f"-h 127.0.0.1 -p {self.port} -k {self.root} -F",
            "start",
        )

    def stop(self) -> None:
        try:
            self._run("pg_ctl", "-D", str(self.root / "data"), "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)

    def url(self, database: str) -> str:
        return f"postgresql://postgres@127.0.0.1:{self.port}/{database}"

    def create_database(self, template: str | None = None) -> str:
        """A new database, empty or a copy of ``template``'s; returns its URL."""
        name = f"acv_{uuid.uuid4().hex[:12]}"
        copy = f' TEMPLATE "{template}"' if template else ""
        with psycopg.connect(self.url("postgres"), autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"{copy}')
        return self.url(name)

    def database_at_head(self) -> str:
        """A new database at the migrations' head; returns its URL. The first is built by
        ``alembic upgrade head``; the next are copies of it (``CREATE DATABASE ... TEMPLATE``,
        a tenth of the time of running every revision again)."""
        if self._head is None:
            url = self.create_database()
            upgrade(url)
            self._head = url.rsplit("/", 1)[1]
        return self.create_database(template=self._head)
