"""Database engine, sessions, migrations and write transactions.

SQLite (the default) runs in WAL mode, so readers never wait for the writer, with foreign
keys on. SQLite allows one writer at a time; :func:`writing` makes writers queue on a lock
instead of polling in SQLite's busy handler, which sleeps in steps of up to 100 ms and would
dominate tail latency under load: a thread lock within the process, and an ``flock`` on a
file next to the database across processes (``acv serve --workers N``, ``acv worker``, run
processes). The lock only orders writers; SQLite's own locking (with a busy timeout) keeps
the data correct whatever the lock does. PostgreSQL needs no such lock.
"""

from __future__ import annotations

import fcntl
import os
import threading
import weakref
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import TypeVar

from alembic import command
from alembic.config import Config
from sqlalchemy import Connection, Engine, create_engine, event, text
from sqlalchemy.orm import Session, sessionmaker

from app.core.resources import MIGRATIONS_DIR
from app.settings import normalise_url

#: Seconds a writer of another process waits for SQLite's lock before failing.
SQLITE_BUSY_TIMEOUT_S = 30.0
#: Connections per engine: a pool of 10 that may grow to this many.
POOL_SIZE, POOL_CAPACITY = 10, 40
#: PostgreSQL advisory-lock key that serialises migrations (any fixed 64-bit number).
MIGRATION_LOCK_KEY = 0x4143_565F_4D49_4752  # "ACV_MIGR"

DB = TypeVar("DB", Session, Connection)


class WriterLock:
    """SQLite's writers queue here: on a thread lock, then (for a database file) on an
    exclusive ``flock`` of ``<database>.writer-lock``, held for the whole transaction.

    Args:
        database: the database file, or ``None`` (in memory: this process only).
    """

    def __init__(self, database: Path | None) -> None:
        self._threads = threading.Lock()
        self._path = None if database is None else Path(f"{database}.writer-lock")
        self._fd: int | None = None

    def __enter__(self) -> None:
        self._threads.acquire()
        try:
            if self._path is not None:
                if self._fd is None:  # opened once; not inherited by child processes
                    self._fd = os.open(self._path, os.O_RDWR | os.O_CREAT, 0o600)
                    weakref.finalize(self, os.close, self._fd)
                fcntl.flock(self._fd, fcntl.LOCK_EX)
        except BaseException:
            self._threads.release()
            raise

    def __exit__(self, *_: object) -> None:
        try:
            if self._fd is not None:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
        finally:
            self._threads.release()


_write_locks: weakref.WeakKeyDictionary[Engine, WriterLock] = weakref.WeakKeyDictionary()


def make_engine(url: str, *, processes: int = 1) -> Engine:
    """A SQLAlchemy engine for ``url``; SQLite gets WAL, foreign keys and a busy timeout.

    Args:
        processes: server processes sharing the database (``acv serve --workers``): each
            keeps ``POOL_SIZE / processes`` idle PostgreSQL connections (at least 4), so the
            idle total stays put; the capacity per process stays :data:`POOL_CAPACITY`.
    """
    url = normalise_url(url)
    pool_size = max(4, -(-POOL_SIZE // processes))
    if not url.startswith("sqlite"):
        return create_engine(
            url, pool_pre_ping=True, pool_size=pool_size, max_overflow=POOL_CAPACITY - pool_size
        )
    database = None
    if ":memory:" not in url and url.startswith("sqlite:///"):
        database = Path(url.removeprefix("sqlite:///"))
        database.parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(
        url,
        pool_size=POOL_SIZE,
        max_overflow=POOL_CAPACITY - POOL_SIZE,
        connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_S},
    )
    event.listen(engine, "connect", _sqlite_pragmas)
    _write_locks[engine] = WriterLock(database)
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
def writing(db: DB) -> Iterator[DB]:
    """A write transaction on a session or a plain connection: commit on success, roll back
    on any error.

    On SQLite it holds this engine's writer lock for the whole transaction.
    """
    lock = _write_locks.get(engine_of(db))
    with lock if lock is not None else nullcontext():
        try:
            yield db
            db.commit()
        except BaseException:
            db.rollback()
            raise


def engine_of(db: Session | Connection) -> Engine:
    """The engine behind a session or a connection (a session bound to a connection
    reports that connection as its bind)."""
    if isinstance(db, Connection):
        return db.engine
    bind = db.get_bind()
    return bind if isinstance(bind, Engine) else bind.engine


def alembic_config(url: str) -> Config:
    """Alembic's configuration for ``url``: the migrations wherever the package keeps them
    (:mod:`app.core.resources`). ``alembic.ini`` at the repository root is for the plain
    ``alembic`` command in a checkout; a wheel has none and needs none."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR))
    config.set_main_option("path_separator", "os")
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
        connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": MIGRATION_LOCK_KEY})
        yield
    elif connection.dialect.name == "sqlite" and database and database != ":memory:":
        with open(f"{database}.migrate-lock", "a") as lock_file:
            fcntl.flock(lock_file, fcntl.LOCK_EX)  # released when the file is closed
            yield
    else:
        yield


def downgrade(url: str, revision: str = "base") -> None:
    command.downgrade(alembic_config(url), revision)
