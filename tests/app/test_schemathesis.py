"""Schemathesis against the app's own OpenAPI schema: every operation, as the researcher
and as a participant, answers without a 5xx and as its schema says (status codes, content
types, bodies, headers), and refuses requests without credentials.

In-process (ASGI) on the ``client`` fixture's app, so on SQLite and PostgreSQL. Examples are
derandomised and few, to stay quick in ``make test``; ``ACV_SCHEMATHESIS_EXAMPLES`` raises
the count for a longer run.
"""

from __future__ import annotations

import os
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from schemathesis import GenerationMode, checks

from app.web.ratelimit import LoginLimiter
from tests.app.conftest import ADMIN

EXAMPLES = int(os.environ.get("ACV_SCHEMATHESIS_EXAMPLES", "8"))
#: Checks that need no knowledge of which ids exist (random ids are 404s, which is right).
CHECKS = [checks.not_a_server_error, checks.status_code_conformance,
          checks.content_type_conformance, checks.response_headers_conformance,
          checks.response_schema_conformance, checks.negative_data_rejection,
          checks.ignored_auth]



@pytest.fixture(scope="module", autouse=True)
def unlimited_logins(client) -> None:
    """Schemathesis probes every operation with invalid bearer tokens, all from one address:
    the failed-login limit (see ``test_security_headers``) would soon refuse the researcher's
    own token too, which is right for a server and wrong for this test."""
    client.app.state.login_limiter = LoginLimiter(per_minute=1_000_000)


@pytest.fixture(scope="module")
def api_schema(client) -> Any:
    return schemathesis.openapi.from_asgi("/openapi.json", client.app)


@pytest.fixture(scope="module")
def role_headers(client, study) -> dict[str, dict[str, str]]:
    """Bearer headers of the researcher and of a participant who has labelled once."""
    body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    participant = {"Authorization": f"Bearer {body['token']}"}
    match = client.get("/api/participants/me/next-match", headers=participant).json()
    client.post(f"/api/matches/{match['match_id']}/label", headers=participant,
                json={"winner": match["a"]["candidate_id"]})
    return {"researcher": ADMIN, "participant": participant}


def conformance_failures(operation: Any, role_headers: dict[str, dict[str, str]],
                         calls: list[int]) -> str | None:
    """Run one operation's valid and invalid examples as both roles; the failure, if any.
    Appends the number of requests made to ``calls``."""
    cases = st.one_of(operation.as_strategy(mode) for mode in
                      (GenerationMode.POSITIVE, GenerationMode.NEGATIVE))
    calls.append(0)

    @given(case=cases)
    @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck), phases=[Phase.explicit, Phase.generate])
    def run(case: Any) -> None:
        for headers in role_headers.values():
            calls[-1] += 1
            case.call_and_validate(headers=headers, checks=CHECKS)

    try:
        run()
    except (Exception, BaseExceptionGroup) as exc:  # says what failed and how to reproduce
        return f"{operation.label}: {exc}"
    return None


def test_every_operation_conforms_to_the_schema(api_schema, role_headers) -> None:
    operations = [result.ok() for result in api_schema.get_all_operations()]
    assert len(operations) >= 20
    calls: list[int] = []
    failures = [f for op in operations if (f := conformance_failures(op, role_headers, calls))]
    print(f"schemathesis: {len(operations)} operations, {sum(calls)} requests, "
          f"{len(failures)} failing")
    assert failures == [], "\n\n".join(failures)
    assert min(calls) > 0
