"""Settings from the environment, the admin token file, and credential helpers."""

from __future__ import annotations

import stat

import pytest

from app.services.auth import (
    ADMIN_TOKEN_FILE,
    bearer_token,
    ensure_admin_token,
    is_researcher,
    researcher_cookie_value,
)
from app.settings import Settings, normalise_url


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


@pytest.mark.parametrize(("url", "expected"), [
    ("postgres://a@b/c", "postgresql+psycopg://a@b/c"),
    ("postgresql+psycopg://a@b/c", "postgresql+psycopg://a@b/c"),
    ("sqlite:///x.db", "sqlite:///x.db"),
])
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
    assert ensure_admin_token(Settings(data_dir=tmp_path, admin_token="given")) == "given"
    assert not (tmp_path / ADMIN_TOKEN_FILE).exists()


@pytest.mark.parametrize(("header", "token"), [
    ("Bearer abc", "abc"), ("bearer abc", "abc"), ("Basic abc", None), ("Bearer ", None),
    ("", None), (None, None),
])
def test_bearer_token(header: str | None, token: str | None) -> None:
    assert bearer_token(header) == token


def test_researcher_proof() -> None:
    cookie = researcher_cookie_value("adm")
    assert cookie != "adm"
    assert is_researcher(admin_token="adm", bearer="adm")
    assert is_researcher(admin_token="adm", cookie=cookie)
    assert not is_researcher(admin_token="adm", bearer="ad")
    assert not is_researcher(admin_token="adm", cookie="adm")  # the raw token is no cookie
    assert not is_researcher(admin_token="adm", bearer="\u00e9")
