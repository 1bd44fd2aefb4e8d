"""Rate limiting of failed researcher logins, per client address (the ``limits`` library).

Failures are wrong tokens posted to the login form and API bearer tokens that are neither the
admin token nor an invite token (:mod:`app.http.deps`). An address may fail
:data:`FAILED_LOGINS_PER_MINUTE` times in any moving minute; after that the login form and
researcher bearer tokens get 429 without the token being compared, until the oldest failure
is a minute old. Successful logins are not counted.

The app's failed-login counts live in its database (:mod:`app.http.lockouts`), shared by
every process and host. Other counts (new people per address through open links) live in
this process's memory, or, with several web workers (``acv serve --workers N``), in a small
SQLite file in the data dir that all of them share (:class:`SharedFailures`). Behind a reverse
proxy every client shares the proxy's address unless the proxy is named in
``ACV_FORWARDED_ALLOW_IPS`` (:mod:`app.settings`): only then is its ``X-Forwarded-For``
believed.
"""

from __future__ import annotations

import contextlib
import math
import sqlite3
import time
from pathlib import Path
from typing import Protocol

from fastapi import Request
from limits import RateLimitItemPerMinute
from limits.storage import MemoryStorage
from limits.strategies import MovingWindowRateLimiter

FAILED_LOGINS_PER_MINUTE = 10
_NAMESPACE = "acv-login"
#: New participants one address may create through open links (``/s/<slug>``) per minute,
#: and their shared counts' file.
JOINS_PER_MINUTE = 30
OPEN_LINK_JOINS = "open-link-joins.sqlite3"


class Failures(Protocol):
    """Where counts that several processes share are kept."""

    def blocked(self, address: str) -> bool: ...
    def failed(self, address: str) -> None: ...
    def retry_after_s(self, address: str) -> int: ...


class LoginLimiter:
    """Failed-login counts per client address in a moving one-minute window.

    Args:
        per_minute: failures an address may make in any minute.
        shared: a SQLite file holding the counts for several processes; ``None`` keeps them
            in this process's memory (unless ``store`` is given).
        store: where the counts are kept instead, counted to its own ``per_minute``
            (:class:`app.http.lockouts.DatabaseFailures`: the app's database).
    """

    def __init__(
        self,
        per_minute: int = FAILED_LOGINS_PER_MINUTE,
        *,
        shared: Path | None = None,
        store: Failures | None = None,
    ) -> None:
        self._item = RateLimitItemPerMinute(per_minute)
        self._limiter = MovingWindowRateLimiter(MemoryStorage())
        self._shared: Failures | None = store
        if store is None and shared is not None:
            self._shared = SharedFailures(shared, per_minute)

    def blocked(self, address: str) -> bool:
        """Whether ``address`` used up its failures (checked before the token is)."""
        if self._shared is not None:
            return self._shared.blocked(address)
        return not self._limiter.test(self._item, _NAMESPACE, address)

    def failed(self, address: str) -> None:
        """Count a failed login of ``address``."""
        if self._shared is not None:
            return self._shared.failed(address)
        self._limiter.hit(self._item, _NAMESPACE, address)

    def retry_after_s(self, address: str) -> int:
        """Seconds until ``address`` may try again (at least 1)."""
        if self._shared is not None:
            return self._shared.retry_after_s(address)
        reset_at, _ = self._limiter.get_window_stats(self._item, _NAMESPACE, address)
        return max(1, math.ceil(reset_at - time.time()))


class SharedFailures:
    """The same moving window, kept in a SQLite file that several processes share: one row
    per failure, rows older than the window deleted as new ones come.

    Args:
        path: the file (created when missing).
        per_minute: failures an address may make in any minute.
    """

    WINDOW_S = 60.0

    def __init__(self, path: Path, per_minute: int) -> None:
        self.path, self.per_minute = path, per_minute
        with contextlib.closing(self._connect()) as db:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute(
                "CREATE TABLE IF NOT EXISTS failures (address TEXT NOT NULL, at REAL NOT NULL)"
            )
            db.execute("CREATE INDEX IF NOT EXISTS failures_address ON failures (address, at)")

    def _connect(self) -> sqlite3.Connection:
        return sqlite3.connect(self.path, timeout=10.0, isolation_level=None)

    def _recent(self, db: sqlite3.Connection, address: str) -> list[float]:
        """The address's failures in the window, newest first, at most ``per_minute``."""
        rows = db.execute(
            "SELECT at FROM failures WHERE address = ? AND at > ? ORDER BY at DESC LIMIT ?",
            (address, time.time() - self.WINDOW_S, self.per_minute),
        )
        return [at for (at,) in rows]

    def blocked(self, address: str) -> bool:
        with contextlib.closing(self._connect()) as db:
            return len(self._recent(db, address)) >= self.per_minute

    def failed(self, address: str) -> None:
        now = time.time()
        with contextlib.closing(self._connect()) as db:
            db.execute("BEGIN IMMEDIATE")
            db.execute("DELETE FROM failures WHERE at <= ?", (now - self.WINDOW_S,))
            db.execute("INSERT INTO failures (address, at) VALUES (?, ?)", (address, now))
            db.execute("COMMIT")

    def retry_after_s(self, address: str) -> int:
        with contextlib.closing(self._connect()) as db:
            recent = self._recent(db, address)
        if len(recent) < self.per_minute:
            return 1
        return max(1, math.ceil(recent[-1] + self.WINDOW_S - time.time()))


def client_address(request: Request) -> str:
    """The client's address: the TCP peer's, or the one a trusted proxy forwarded."""
    return request.client.host if request.client else "unknown"


def login_limiter(request: Request) -> LoginLimiter:
    """The app's limiter (one per app, made by :func:`app.main.create_app`)."""
    return request.app.state.login_limiter
