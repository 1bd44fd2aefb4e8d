"""Database engine, sessions, migrations and write transactions.

SQLite (the default) runs in WAL mode, so readers never wait for the writer, with foreign
keys on. SQLite allows one writer at a time; :func:`writing` makes this process's writers
queue on a lock instead of polling in SQLite's busy handler, which sleeps in steps of up to
100 ms and would dominate tail latency under load. PostgreSQL needs no such lock.
"""

from __future__ import annotations

import fcntl
import threading
import weakref
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path

from alembic import command
from alembic.config import Config
from sqlalchemy import Connection, Engine, create_engine, event, text
from sqlalchemy.orm import Session, sessionmaker

from app.settings import normalise_url

ROOT = Path(__file__).resolve().parents[1]
ALEMBIC_INI = ROOT / "alembic.ini"
MIGRATIONS = ROOT / "migrations"
#: Seconds a writer of another process waits for SQLite's lock before failing.
SQLITE_BUSY_TIMEOUT_S = 30.0
#: Connections per engine: a pool of 10 that may grow to this many.
POOL_SIZE, POOL_CAPACITY = 10, 40
#: PostgreSQL advisory-lock key that serialises migrations (any fixed 64-bit number).
MIGRATION_LOCK_KEY = 0x4143_565F_4D49_4752  # "ACV_MIGR"

_write_locks: weakref.WeakKeyDictionary[Engine, threading.Lock] = weakref.WeakKeyDictionary()


def make_engine(url: str) -> Engine:
    """A SQLAlchemy engine for ``url``; SQLite gets WAL, foreign keys and a busy timeout."""
    url = normalise_url(url)
    if not url.startswith("sqlite"):
        return create_engine(url, pool_pre_ping=True, pool_size=POOL_SIZE,
                             max_overflow=POOL_CAPACITY - POOL_SIZE)
    if ":memory:" not in url and url.startswith("sqlite:///"):
        Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(
        url, pool_size=POOL_SIZE, max_overflow=POOL_CAPACITY - POOL_SIZE,
        connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_S})
    event.listen(engine, "connect", _sqlite_pragmas)
    _write_locks[engine] = threading.Lock()
    return engine


def _sqlite_pragmas(dbapi_connection, _record) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")  # durable at checkpoints; safe in WAL mode
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.close()


def make_sessions(engine: Engine) -> sessionmaker[Session]:
    """Session factory; objects stay usable after commit (services return them)."""
    return sessionmaker(engine, expire_on_commit=False)


@contextmanager
def writing(session: Session) -> Iterator[Session]:
    """A write transaction: commit on success, roll back on any error.

    On SQLite it holds this engine's writer lock for the whole transaction.
    """
    lock = _write_locks.get(session.get_bind())
    with lock if lock is not None else nullcontext():
        try:
            yield session
            session.commit()
        except BaseException:
            session.rollback()
            raise


def alembic_config(url: str) -> Config:
    """Alembic's configuration for ``url`` (``alembic.ini`` at the repository root)."""
    config = Config(str(ALEMBIC_INI))
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["url"] = normalise_url(url)
    return config


def upgrade(url: str, revision: str = "head") -> None:
    """Apply migrations up to ``revision``; the only way the schema is created."""
    if url.startswith("sqlite:///") and ":memory:" not in url:
        Path(url.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
    command.upgrade(alembic_config(url), revision)


@contextmanager
def migration_lock(connection: Connection) -> Iterator[None]:
    """Serialise migrations of one database across processes (``migrations/env.py``).

    Several processes may start at once (web workers, ``acv serve`` twice, a ``migrate``
    container); the second waits, then finds the schema at head and does nothing.
    PostgreSQL: a transaction-level advisory lock, released when the migration commits;
    SQLite: an exclusive ``flock`` on a file next to the database.
    """
    database = connection.engine.url.database
    if connection.dialect.name == "postgresql":
        connection.execute(text("SELECT pg_advisory_xact_lock(:key)"),
                           {"key": MIGRATION_LOCK_KEY})
        yield
    elif connection.dialect.name == "sqlite" and database and database != ":memory:":
        with open(f"{database}.migrate-lock", "a") as lock_file:
            fcntl.flock(lock_file, fcntl.LOCK_EX)  # released when the file is closed
            yield
    else:
        yield


def downgrade(url: str, revision: str = "base") -> None:
    command.downgrade(alembic_config(url), revision)
