"""Web-app settings, read from the environment (pydantic-settings).

- ``ACV_DATA_DIR`` (default ``./data``): the SQLite file, rendered images and the generated
  admin token live here.
- ``DATABASE_URL``: a SQLAlchemy URL; unset means SQLite in the data dir. ``postgresql://``
  URLs use the psycopg 3 driver.
- ``ACV_ADMIN_TOKEN``: the researcher's bearer token, at least 32 characters; unset means one
  is generated on first start and kept in the data dir (see
  :func:`app.core.auth.ensure_admin_token`).
- ``ACV_DATASET_SALT``: the secret that participants' pseudonyms in a shared dataset are
  keyed with (at least 32 characters); unset means one is generated on first export and
  kept in the data dir (:func:`app.core.auth.dataset_salt`). The same salt gives the same
  pseudonyms on every re-export; without it they cannot be traced back to anyone.
- ``ACV_SESSION_HOURS`` (default 12): how long a researcher login (the cookie) lasts; the
  server refuses older cookies whatever the browser keeps.
- ``ACV_PUBLIC_URL``: the base of links printed outside a request (by the CLI; default
  ``http://127.0.0.1:8000``, or the address ``acv serve`` listens on); the API uses the
  request's own base URL.
- ``ACV_THREADS`` (default 8): worker threads for request handlers in one server process.
- ``ACV_MIN_FREE_MB`` (default 64): the server refuses to start with less free space in the
  data dir (see :mod:`app.preflight`).
- ``ACV_FORWARDED_ALLOW_IPS`` (default empty): the reverse proxies, comma-separated
  addresses or networks (``10.0.0.0/8``), whose ``X-Forwarded-For`` and
  ``X-Forwarded-Proto`` the app believes. Empty: no one's; the client address is the TCP
  peer's, so a client cannot choose the address its joins and failed logins are counted by.
- ``ACV_WEBHOOK_TARGETS`` (default ``public``): where webhooks may point. ``public``: https
  URLs of public addresses only; ``loopback`` (tests): only 127.0.0.1 and ::1, over http
  too, so that no test ever sends traffic elsewhere (see :mod:`app.webhooks.targets`).
- ``ACV_WEBHOOK_BACKOFF_S`` (default 5) and ``ACV_WEBHOOK_BACKOFF_CAP_S`` (default 3600): a
  failed delivery is retried after ``backoff * 2**(attempts - 1)`` seconds, at most the cap,
  with jitter; after ``ACV_WEBHOOK_MAX_ATTEMPTS`` (default 40: about 31 hours) it gives up.
- ``ACV_WEBHOOK_CONCURRENCY`` (default 8): webhook attempts in flight at once in a delivering
  process, at most one per webhook, so that receivers that stall hold up no other (see
  :mod:`app.webhooks.scheduler`).
- ``ACV_LOG_FORMAT`` (default ``text``): the server's log lines (each with a UTC timestamp
  and a level), as ``text`` or as one JSON object a line, ``json`` (see :mod:`app.core.logs`).
"""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import Literal

from pydantic import AliasChoices, Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

SQLITE_FILE = "acv.sqlite3"
#: How server log lines are written (``ACV_LOG_FORMAT``).
LogFormat = Literal["text", "json"]


class Settings(BaseSettings):
    """Everything the app reads from the environment; frozen once built."""

    model_config = SettingsConfigDict(env_prefix="ACV_", extra="ignore", frozen=True)

    data_dir: Path = Path("data")
    database_url: str | None = Field(
        default=None, validation_alias=AliasChoices("DATABASE_URL", "ACV_DATABASE_URL")
    )
    admin_token: SecretStr | None = None
    dataset_salt: SecretStr | None = None
    public_url: str | None = None
    threads: int = Field(default=8, ge=1, le=256)
    min_free_mb: int = Field(default=64, ge=0)
    session_hours: float = Field(default=12.0, gt=0, le=24 * 90)
    forwarded_allow_ips: str = ""
    webhook_targets: Literal["public", "loopback"] = "public"
    webhook_backoff_s: float = Field(default=5.0, gt=0, le=3600)
    webhook_backoff_cap_s: float = Field(default=3600.0, gt=0, le=86_400)
    webhook_max_attempts: int = Field(default=40, ge=1, le=1000)
    webhook_concurrency: int = Field(default=8, ge=1, le=256)
    log_format: LogFormat = "text"

    @field_validator("forwarded_allow_ips")
    @classmethod
    def _proxy_addresses(cls, value: str) -> str:
        """Every entry an IP address or network: uvicorn would take a typo as a host name
        that never matches, and the proxy would silently stay untrusted."""
        for entry in _entries(value):
            try:
                ipaddress.ip_network(entry, strict=False)
            except ValueError:
                raise ValueError(f"not an IP address or network: {entry!r}") from None
        return value

    @property
    def trusted_proxies(self) -> list[str]:
        """The addresses and networks of ``ACV_FORWARDED_ALLOW_IPS`` (empty: none)."""
        return _entries(self.forwarded_allow_ips)

    @property
    def session_max_age_s(self) -> int:
        """Seconds a researcher cookie is accepted after login."""
        return max(1, round(self.session_hours * 3600))

    @property
    def sqlalchemy_url(self) -> str:
        """The database URL with an explicit driver (psycopg 3 for PostgreSQL)."""
        return normalise_url(self.database_url or f"sqlite:///{self.data_dir / SQLITE_FILE}")

    @property
    def images_dir(self) -> Path:
        """Where rendered candidate images are stored (a content-addressed cache)."""
        return self.data_dir / "images"


def _entries(value: str) -> list[str]:
    return [e.strip() for e in value.split(",") if e.strip()]


def normalise_url(url: str) -> str:
    """Pick psycopg 3 for bare PostgreSQL URLs (SQLAlchemy's default would be psycopg2)."""
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url.removeprefix(prefix)
    return url
