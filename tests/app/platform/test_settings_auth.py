"""Settings from the environment, the admin token file, and credential helpers."""

from __future__ import annotations

import stat
import time

import pytest

from app.core.auth import (
    ADMIN_TOKEN_FILE,
    MIN_ADMIN_TOKEN_CHARS,
    bearer_token,
    ensure_admin_token,
    is_researcher,
    researcher_cookie_value,
    valid_researcher_cookie,
)
from app.settings import Settings, normalise_url
from engine.errors import InputError

ADM = "adm-0123456789abcdefghijklmnopqrstuvwxyz"


def test_settings_come_from_the_environment(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("ACV_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("DATABASE_URL", "postgresql://u@h:5/db")
    monkeypatch.setenv("ACV_ADMIN_TOKEN", "s3cret")
    settings = Settings()
    assert settings.data_dir == tmp_path
    assert settings.sqlalchemy_url == "postgresql+psycopg://u@h:5/db"
    assert settings.admin_token.get_secret_value() == "s3cret"
    assert "s3cret" not in repr(settings)


def test_default_database_is_sqlite_in_the_data_dir(monkeypatch, tmp_path) -> None:
    monkeypatch.delenv("DATABASE_URL", raising=False)
    assert Settings(data_dir=tmp_path).sqlalchemy_url == f"sqlite:///{tmp_path}/acv.sqlite3"


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("postgres://a@b/c", "postgresql+psycopg://a@b/c"),
        ("postgresql+psycopg://a@b/c", "postgresql+psycopg://a@b/c"),
        ("sqlite:///x.db", "sqlite:///x.db"),
    ],
)
def test_normalise_url(url: str, expected: str) -> None:
    assert normalise_url(url) == expected


def test_admin_token_is_generated_once_and_kept_private(monkeypatch, tmp_path) -> None:
    monkeypatch.delenv("ACV_ADMIN_TOKEN", raising=False)
    settings = Settings(data_dir=tmp_path / "data")
    token = ensure_admin_token(settings)
    assert len(token) >= 40
    assert ensure_admin_token(settings) == token
    mode = (tmp_path / "data" / ADMIN_TOKEN_FILE).stat().st_mode
    assert stat.S_IMODE(mode) == 0o600


def test_explicit_admin_token_wins(tmp_path) -> None:
    assert ensure_admin_token(Settings(data_dir=tmp_path, admin_token=ADM)) == ADM
    assert not (tmp_path / ADMIN_TOKEN_FILE).exists()


@pytest.mark.parametrize(
    "short", ["a", "x" * (MIN_ADMIN_TOKEN_CHARS - 1), " " + "y" * (MIN_ADMIN_TOKEN_CHARS - 1) + " "]
)
def test_short_admin_tokens_are_refused(tmp_path, short: str) -> None:
    with pytest.raises(InputError, match=f"at least {MIN_ADMIN_TOKEN_CHARS}"):
        ensure_admin_token(Settings(data_dir=tmp_path, admin_token=short))
    (tmp_path / ADMIN_TOKEN_FILE).write_text(short.strip() + "\n")  # a hand-edited file too
    with pytest.raises(InputError, match=ADMIN_TOKEN_FILE):
        ensure_admin_token(Settings(data_dir=tmp_path))
    assert ensure_admin_token(Settings(data_dir=tmp_path, admin_token="z" * 32)) == "z" * 32


@pytest.mark.parametrize(
    ("header", "token"),
    [
        ("Bearer abc", "abc"),
        ("bearer abc", "abc"),
        ("Basic abc", None),
        ("Bearer ", None),
        ("", None),
        (None, None),
    ],
)
def test_bearer_token(header: str | None, token: str | None) -> None:
    assert bearer_token(header) == token


def test_researcher_proof() -> None:
    cookie = researcher_cookie_value(admin_token=ADM)
    assert ADM not in cookie and cookie != researcher_cookie_value(admin_token=ADM)  # nonce
    assert is_researcher(admin_token=ADM, bearer=ADM)
    assert is_researcher(admin_token=ADM, cookie=cookie, max_age_s=60)
    assert not is_researcher(admin_token=ADM, cookie=cookie)  # no session length: no cookie
    assert not is_researcher(admin_token=ADM, bearer=ADM[:-1])
    assert not is_researcher(admin_token=ADM, cookie=ADM, max_age_s=60)  # the raw token
    assert not is_researcher(admin_token=ADM, bearer="\u00e9")
    assert not is_researcher(admin_token=ADM + "x", cookie=cookie, max_age_s=60)  # new token


def test_researcher_cookies_expire_on_the_server() -> None:
    now = time.time()
    cookie = researcher_cookie_value(admin_token=ADM, issued_at=now - 3600)
    for age_limit, accepted in ((3601, True), (3599, False)):
        assert (
            valid_researcher_cookie(cookie=cookie, admin_token=ADM, max_age_s=age_limit, now=now)
            is accepted
        )
    future = researcher_cookie_value(admin_token=ADM, issued_at=now + 3600)
    assert not valid_researcher_cookie(cookie=future, admin_token=ADM, max_age_s=10**9, now=now)


def test_tampered_researcher_cookies_are_refused() -> None:
    now = time.time()
    issued, nonce, signature = researcher_cookie_value(admin_token=ADM, issued_at=now - 100).split(
        "."
    )
    flipped = signature[:-1] + ("1" if signature[-1] == "0" else "0")

    def accepted(value: str) -> bool:
        return valid_researcher_cookie(cookie=value, admin_token=ADM, max_age_s=3600, now=now)

    assert accepted(f"{issued}.{nonce}.{signature}")
    for forged in (
        f"{int(now)}.{nonce}.{signature}",  # a renewed login time
        f"{issued}.{nonce}x.{signature}",
        f"{issued}.{nonce}.{flipped}",
        f"{issued}.{nonce}",
        f"{issued}.{nonce}.{signature}.x",
        f"-5.{nonce}.x",
        f"\u0661\u0662.{nonce}.{signature}",
        "",
        "x" * 300,
    ):
        assert not accepted(forged), forged
