"""Failed researcher logins counted in the app's database (issue 45 §4), so that the lockout
holds for the server as a whole: every process of ``acv serve --workers N`` or of Compose's
``uvicorn --workers 4``, and every host on one PostgreSQL.

One row per failure (``login_failures``); an address that failed
:data:`app.http.ratelimit.FAILED_LOGINS_PER_MINUTE` times in a moving minute is blocked
until the oldest of those failures is a minute old, as the in-memory limiter does. A process
that has seen an address blocked keeps "blocked until" for it in memory and neither reads nor
writes the database for it until then, so an attack adds no write per request (blocked
requests are refused before their token is compared, and are not failures). Rows older than
the window are deleted as new failures come.
"""

from __future__ import annotations

import math
import threading
from datetime import datetime, timedelta

from sqlalchemy import Engine, delete, insert, select

from app.db import writing
from app.models import LoginFailure, as_utc, utcnow

#: The longest address stored (a trusted proxy's forwarded value may be anything).
MAX_ADDRESS_CHARS = 200


class DatabaseFailures:
    """The moving window of failed logins per address, in the app's database.

    Args:
        engine: the app's database (``login_failures`` is its table).
        per_minute: failures an address may make in any minute.
        max_cached: addresses whose "blocked until" this process keeps at most; past it,
            blocked addresses are read from the database each time.
    """

    WINDOW = timedelta(seconds=60)

    def __init__(self, engine: Engine, per_minute: int, *, max_cached: int = 10_000) -> None:
        self._engine, self.per_minute, self._max_cached = engine, per_minute, max_cached
        self._until: dict[str, datetime] = {}
        self._lock = threading.Lock()

    def blocked(self, address: str) -> bool:
        """Whether ``address`` used up its failures (checked before the token is)."""
        return self._blocked_until(address[:MAX_ADDRESS_CHARS]) is not None

    def failed(self, address: str) -> None:
        """Count a failed login of ``address``, and prune the failures the window has left
        behind; nothing while this process knows the address is blocked."""
        address = address[:MAX_ADDRESS_CHARS]
        if self._cached(address) is not None:
            return
        now = utcnow()
        with self._engine.connect() as conn, writing(conn):
            conn.execute(delete(LoginFailure).where(LoginFailure.at <= now - self.WINDOW))
            conn.execute(insert(LoginFailure).values(address=address, at=now))

    def retry_after_s(self, address: str) -> int:
        """Seconds until ``address`` may try again (at least 1)."""
        until = self._blocked_until(address[:MAX_ADDRESS_CHARS])
        return 1 if until is None else max(1, math.ceil((until - utcnow()).total_seconds()))

    def _blocked_until(self, address: str) -> datetime | None:
        """When ``address`` is free again, or ``None`` if it is now."""
        if (until := self._cached(address)) is not None:
            return until
        now = utcnow()
        with self._engine.connect() as conn:
            recent = list(
                conn.scalars(
                    select(LoginFailure.at)
                    .where(LoginFailure.address == address, LoginFailure.at > now - self.WINDOW)
                    .order_by(LoginFailure.at.desc())
                    .limit(self.per_minute)
                )
            )
        if len(recent) < self.per_minute:
            return None
        until = as_utc(recent[-1]) + self.WINDOW
        self._remember(address, until, now)
        return until

    def _cached(self, address: str) -> datetime | None:
        """This process's "blocked until" of ``address``, while it is in the future."""
        with self._lock:
            until = self._until.get(address)
            if until is not None and until <= utcnow():
                del self._until[address]
                return None
            return until

    def _remember(self, address: str, until: datetime, now: datetime) -> None:
        with self._lock:
            if len(self._until) >= self._max_cached:
                self._until = {a: u for a, u in self._until.items() if u > now}
            if len(self._until) < self._max_cached:
                self._until[address] = until
