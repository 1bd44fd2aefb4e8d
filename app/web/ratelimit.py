"""Rate limiting of failed researcher logins, per client address (the ``limits`` library).

Failures are wrong tokens posted to the login form and API bearer tokens that are neither the
admin token nor an invite token (:mod:`app.api.deps`). An address may fail
:data:`FAILED_LOGINS_PER_MINUTE` times in any moving minute; after that the login form and
researcher bearer tokens get 429 without the token being compared, until the oldest failure
is a minute old. Successful logins are not counted.

The counts live in this process's memory. With several web workers (``uvicorn --workers
N``) each worker counts on its own, so an address may fail up to N times the limit, and
behind a reverse proxy every client shares the proxy's address unless uvicorn trusts its
``X-Forwarded-For`` (``--proxy-headers --forwarded-allow-ips``).
"""

from __future__ import annotations

import math
import time

from fastapi import Request
from limits import RateLimitItemPerMinute
from limits.storage import MemoryStorage
from limits.strategies import MovingWindowRateLimiter

FAILED_LOGINS_PER_MINUTE = 10
_NAMESPACE = "acv-login"


class LoginLimiter:
    """Failed-login counts per client address in a moving one-minute window.

    Args:
        per_minute: failures an address may make in any minute.
    """

    def __init__(self, per_minute: int = FAILED_LOGINS_PER_MINUTE) -> None:
        self._item = RateLimitItemPerMinute(per_minute)
        self._limiter = MovingWindowRateLimiter(MemoryStorage())

    def blocked(self, address: str) -> bool:
        """Whether ``address`` used up its failures (checked before the token is)."""
        return not self._limiter.test(self._item, _NAMESPACE, address)

    def failed(self, address: str) -> None:
        """Count a failed login of ``address``."""
        self._limiter.hit(self._item, _NAMESPACE, address)

    def retry_after_s(self, address: str) -> int:
        """Seconds until ``address`` may try again (at least 1)."""
        reset_at, _ = self._limiter.get_window_stats(self._item, _NAMESPACE, address)
        return max(1, math.ceil(reset_at - time.time()))


def client_address(request: Request) -> str:
    """The client's address as the server sees it (after uvicorn's proxy-header handling)."""
    return request.client.host if request.client else "unknown"


def login_limiter(request: Request) -> LoginLimiter:
    """The app's limiter (one per app, made by :func:`app.main.create_app`)."""
    return request.app.state.login_limiter
