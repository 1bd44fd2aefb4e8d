"""Deep and wide JSON bodies on every JSON operation (issue 24, F1), on PostgreSQL.

Property tests (hypothesis, derandomised: the same examples on every run) over every
operation of the OpenAPI document whose body is JSON: a value nested thousands deep, or a
list or object tens of thousands wide, under one of the body's own fields (so validation
reaches it) or an unknown one, beside a long text or not. Without credentials the answer is
401, whatever the body (credentials are checked before it is parsed); with them it is a
4xx. Never a 5xx; the answer and the log lines it causes stay small.
"""

from __future__ import annotations

import logging
import re
from typing import Any

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.http.ratelimit import LoginLimiter
from tests.support.openapi import JsonOperation, api_openapi, json_operations
from tests.support.surveys import scheme_headers

# postgres_only: a sweep of every route: validation and authorization are its subject, not storage.
pytestmark = pytest.mark.postgres_only

OPERATIONS = json_operations(api_openapi())
#: Largest answer to a bad body, and largest log output of one request (bytes).
MAX_ANSWER = 8 * 1024
MAX_LOG = 2 * 1024
MAX_DEPTH = 5000
MAX_WIDTH = 50_000
CHECKS = settings(
    max_examples=12,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _deep(depth: int, kind: str) -> str:
    opening, closing = ('{"a":', "}") if kind == "object" else ("[", "]")
    return opening * depth + "1" + closing * depth


def _wide(width: int, kind: str) -> str:
    if kind == "object":
        return "{" + ",".join(f'"k{i}":{i}' for i in range(width)) + "}"
    return "[" + ",".join(["1.5"] * width) + "]"


@st.composite
def bodies(draw: st.DrawFn, op: JsonOperation) -> str:
    """A JSON body holding a deep or wide value."""
    shape = draw(st.sampled_from(["deep", "wide"]))
    kind = draw(st.sampled_from(["object", "array"]))
    # the depths the probe reported (500: a 500; 900: a reset connection) and beyond
    # Python's recursion limit, besides any other
    depths = st.sampled_from([500, 900, 2000, MAX_DEPTH]) | st.integers(1, MAX_DEPTH)
    value = (
        _deep(draw(depths), kind)
        if shape == "deep"
        else _wide(draw(st.integers(1, MAX_WIDTH)), kind)
    )
    if draw(st.booleans()):
        return value  # the body itself
    names = sorted(op.schema.get("properties", {})) or ["answers", "winner", "name"]
    key = draw(st.sampled_from([*names, "unknown"]))
    pad = draw(st.sampled_from([0, 100, 100_000]))
    return '{"padding": "' + "x" * pad + '", "' + key + '": ' + value + "}"


@pytest.fixture(scope="module")
def credentials(client: TestClient, study: dict[str, Any]) -> dict[str, dict[str, str]]:
    return scheme_headers(client, study["id"])


def _send(client: TestClient, op: JsonOperation, body: str, headers: dict[str, str]) -> Any:
    url = re.sub(r"\{[^}]+\}", "1", op.path)
    return client.request(
        op.method, url, content=body, headers=headers | {"Content-Type": "application/json"}
    )


def _bounded(response: Any, caplog: pytest.LogCaptureFixture) -> None:
    assert response.status_code < 500, response.text[:500]
    assert len(response.content) <= MAX_ANSWER, response.text[:500]
    assert sum(len(r.getMessage()) for r in caplog.records) <= MAX_LOG, caplog.text[:500]


def test_every_json_operation_is_covered() -> None:
    assert {str(op) for op in OPERATIONS} >= {
        "POST /api/matches/{match_id}/label",
        "POST /api/studies",
        "POST /api/surveys",
        "POST /api/surveys/me/screens/{position}/answers",
        "PUT /api/studies/{study_id}/crowd",
        "POST /api/runs",
    }
    assert all(op.schemes for op in OPERATIONS)


@pytest.mark.parametrize("body", ["{not json", '{"a": 1', "\xff", ""])
@pytest.mark.parametrize("op", OPERATIONS, ids=str)
def test_without_credentials_a_body_is_not_even_parsed(
    client: TestClient, op: JsonOperation, body: str
) -> None:
    response = _send(client, op, body, {})
    assert response.status_code == 401, response.text


@pytest.mark.parametrize("op", OPERATIONS, ids=str)
def test_wrong_credentials_are_401_before_the_body_is_parsed(
    client: TestClient, op: JsonOperation
) -> None:
    client.app.state.login_limiter = LoginLimiter()  # one failure here, not a lockout
    wrong = {"Authorization": "Bearer " + "x" * 43}
    response = _send(client, op, "{not json", wrong)
    assert response.status_code == 401, response.text


@pytest.mark.parametrize("op", OPERATIONS, ids=str)
def test_without_credentials_any_body_is_401(
    client: TestClient, caplog: pytest.LogCaptureFixture, op: JsonOperation
) -> None:
    @CHECKS
    @given(body=bodies(op))
    def check(body: str) -> None:
        caplog.clear()
        response = _send(client, op, body, {})
        _bounded(response, caplog)
        assert response.status_code == 401, response.text[:500]

    caplog.set_level(logging.INFO)
    check()


@pytest.mark.parametrize("op", OPERATIONS, ids=str)
def test_with_credentials_deep_and_wide_bodies_are_small_4xx(
    client: TestClient, credentials, caplog: pytest.LogCaptureFixture, op: JsonOperation
) -> None:
    headers = credentials[op.schemes[0]]

    @CHECKS
    @given(body=bodies(op))
    def check(body: str) -> None:
        caplog.clear()
        response = _send(client, op, body, headers)
        _bounded(response, caplog)
        assert 400 <= response.status_code < 500, response.text[:500]

    caplog.set_level(logging.INFO)
    check()
