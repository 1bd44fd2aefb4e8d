"""``X-Forwarded-For`` is believed only from the proxies named in ``ACV_FORWARDED_ALLOW_IPS``
(issue 24, F6): by default a client cannot choose the address its joins and failed logins
are counted by. In process on SQLite and PostgreSQL, and through ``acv serve --workers 2`` as
users start it (its processes count failed logins together; one process passes the same
uvicorn options and builds the same app as the in-process tests)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from app.http.ratelimit import FAILED_LOGINS_PER_MINUTE, LoginLimiter
from app.main import create_app
from app.settings import Settings
from tests.support.crowd import configure, join
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env
from tests.support.web import ADMIN_TOKEN

WRONG = {"Authorization": "Bearer " + "x" * 40}


@contextmanager
def proxied_app(settings: Settings, proxies: str) -> Iterator[TestClient]:
    """The app with ``ACV_FORWARDED_ALLOW_IPS=proxies``, its requests from 127.0.0.1."""
    app = create_app(settings.model_copy(update={"forwarded_allow_ips": proxies}))
    with TestClient(app, client=("127.0.0.1", 50000), follow_redirects=False) as client:
        client.app.state.join_limiter = LoginLimiter(2)
        yield client


def _joins(client: TestClient, slug: str, forwarded: list[str]) -> list[int]:
    """The status of one open-link visit (a fresh browser) per ``X-Forwarded-For`` value."""
    codes = []
    for address in forwarded:
        client.cookies.clear()
        codes.append(join(client, f"/s/{slug}", headers={"X-Forwarded-For": address}).status_code)
    return codes


@pytest.mark.parametrize(
    ("proxies", "forwarded", "codes"),
    [
        ("", ["1.1.1.1", "2.2.2.2", "3.3.3.3"], [303, 303, 429]),  # all counted as 127.0.0.1
        ("10.0.0.0/8", ["1.1.1.1", "2.2.2.2", "3.3.3.3"], [303, 303, 429]),  # not our proxy
        ("127.0.0.1", ["1.1.1.1", "2.2.2.2", "3.3.3.3"], [303, 303, 303]),
        ("127.0.0.0/8, ::1", ["1.1.1.1", "1.1.1.1", "1.1.1.1", "2.2.2.2"], [303, 303, 429, 303]),
    ],
)
def test_join_limit_counts_by_the_trusted_address(
    settings: Settings, make_study, proxies: str, forwarded: list[str], codes: list[int]
) -> None:
    with proxied_app(settings, proxies) as client:
        study = make_study()
        link = configure(client, study["id"])
        assert _joins(client, link["slug"], forwarded) == codes


@pytest.mark.parametrize("bad", ["proxy.example", "*", "10.0.0.0/33", "1.2.3.4, nope"])
def test_a_proxy_that_is_not_an_address_is_refused(tmp_path: Path, bad: str) -> None:
    with pytest.raises(ValidationError, match="not an IP address or network"):
        Settings(data_dir=tmp_path, forwarded_allow_ips=bad)


def _failed_logins(base: str, forwarded: list[str]) -> list[int]:
    return [
        httpx.get(
            f"{base}/api/studies", headers=WRONG | {"X-Forwarded-For": a}, timeout=HTTP_TIMEOUT_S
        ).status_code
        for a in forwarded
    ]


SPOOFED = [f"203.0.113.{i}" for i in range(FAILED_LOGINS_PER_MINUTE + 1)]
LOCKED = [401] * FAILED_LOGINS_PER_MINUTE + [429]


@pytest.mark.process
def test_acv_serve_ignores_forwarded_headers_by_default(tmp_path: Path) -> None:
    env = clean_env(ACV_DATA_DIR=str(tmp_path), ACV_ADMIN_TOKEN=ADMIN_TOKEN)
    with acv_serve(env, tmp_path / "serve.log", "--workers", "2") as base:
        assert _failed_logins(base, SPOOFED) == LOCKED


@pytest.mark.process
def test_acv_serve_believes_the_configured_proxy(tmp_path: Path) -> None:
    env = clean_env(
        ACV_DATA_DIR=str(tmp_path), ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_FORWARDED_ALLOW_IPS="127.0.0.1"
    )
    with acv_serve(env, tmp_path / "serve.log", "--workers", "2") as base:
        assert set(_failed_logins(base, SPOOFED)) == {401}  # one failure per client
        same = ["198.51.100.7"] * (FAILED_LOGINS_PER_MINUTE + 1)
        assert _failed_logins(base, same) == LOCKED
        assert _failed_logins(base, ["198.51.100.8"]) == [401]
