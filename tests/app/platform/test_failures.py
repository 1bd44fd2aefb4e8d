"""A failure the request did not cause (the database down, a value it cannot store, a bug)
answers the API in JSON and a browser's page in HTML, never the API's JSON on a page and
never a stack trace; a participant whose answer hit it reads what to do."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.exc import DataError, OperationalError

from app.main import create_app
from app.studies import service as studies
from tests.support.web import ADMIN, ADMIN_TOKEN, logged_in

#: failure -> (status, the API's detail, words of the page)
FAILURES: dict[str, tuple[Exception, int, str, str]] = {
    "database down": (
        OperationalError("SELECT 1", {}, Exception("connection refused")),
        503,
        "the database is unavailable; try again",
        "Nothing was lost",
    ),
    "unstorable value": (
        DataError("INSERT", {}, Exception("value too long")),
        422,
        "a value in the request cannot be stored",
        "check what you typed",
    ),
    "a bug": (RuntimeError("boom"), 500, "internal server error", "went wrong on our side"),
}


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    """The app, answering a bug with its 500 instead of raising it into the test."""
    with TestClient(create_app(settings), raise_server_exceptions=False) as test_client:
        yield test_client


@pytest.mark.parametrize("failure", FAILURES)
def test_a_page_gets_a_page_and_the_api_json(client, monkeypatch, failure: str) -> None:
    exc, status, detail, words = FAILURES[failure]

    def fails(*_: object, **__: object) -> None:
        raise exc

    page = logged_in(client, raise_server_exceptions=False)
    monkeypatch.setattr(studies, "list_studies", fails)
    shown = page.get("/studies", headers={"Accept": "text/html"})
    assert shown.status_code == status and shown.headers["content-type"].startswith("text/html")
    assert words in shown.text and "Traceback" not in shown.text and ADMIN_TOKEN not in shown.text
    api = client.get("/api/studies", headers=ADMIN)
    assert (api.status_code, api.json()) == (status, {"detail": detail})
    if status == 503:
        assert shown.headers["retry-after"] == api.headers["retry-after"] == "1"
