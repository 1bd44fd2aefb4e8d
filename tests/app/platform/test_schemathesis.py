"""Schemathesis against the app's own OpenAPI schema: every operation, as the researcher
and as a participant, answers without a 5xx and as its schema says (status codes, content
types, bodies, headers), and refuses requests without credentials.

Two phases: fuzzing (random valid and invalid requests, derandomised and few, to stay quick
in ``make test``; ``ACV_SCHEMATHESIS_EXAMPLES`` raises the count for a longer run) and
negative coverage (schemathesis's deterministic walk over every way to violate the schema
in each parameter and body field, e.g. ``true`` or ``1.5`` where an integer belongs; each
must be refused with a documented 4xx, never accepted nor a 5xx). Coverage requests carry
the credentials of the operation's own security scheme. Its valid cases are left out: they
would create studies and runs whose rendering and training load the machine for minutes.

In-process (ASGI) on the ``client`` fixture's app, on PostgreSQL (the
stricter backend; ``test_bad_input`` runs SQLite's own limits).
"""

from __future__ import annotations

import os
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st
from schemathesis import GenerationMode, checks
from schemathesis.core.parameters import ParameterLocation
from schemathesis.generation.drivers import CoverageGenerator
from schemathesis.generation.feedback import FeedbackSources
from schemathesis.generation.overrides import Override

from app.http.ratelimit import LoginLimiter
from tests.support.evaluations import evaluator_headers
from tests.support.surveys import finished, paper_body
from tests.support.surveys import invite as invite_respondents
from tests.support.web import ADMIN

# postgres_only: a sweep of every route: validation and authorization are its subject, not storage.
pytestmark = pytest.mark.postgres_only

EXAMPLES = int(os.environ.get("ACV_SCHEMATHESIS_EXAMPLES", "8"))
#: Checks that need no knowledge of which ids exist (random ids are 404s, which is right).
CHECKS = [
    checks.not_a_server_error,
    checks.status_code_conformance,
    checks.content_type_conformance,
    checks.response_headers_conformance,
    checks.response_schema_conformance,
    checks.negative_data_rejection,
    checks.ignored_auth,
]
#: Security scheme (as the schema names it) -> the role whose credentials it takes.
SCHEME_ROLES = {
    "AdminToken": "researcher",
    "InviteToken": "participant",
    "SurveyInviteToken": "respondent",
    "EvaluatorInviteToken": "evaluator",
}


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
    client.post(
        f"/api/matches/{match['match_id']}/label",
        headers=participant,
        json={"winner": match["a"]["candidate_id"]},
    )
    return {"researcher": ADMIN, "participant": participant}


@pytest.fixture(scope="module")
def scheme_headers(client, study, role_headers) -> dict[str, dict[str, str]]:
    """Bearer headers per security scheme, a survey respondent's and an evaluator's
    included."""
    trees = [
        {"kind": "participant", "participant_id": finished(client, study["id"], side)}
        for side in ("a", "b")
    ]
    survey = client.post("/api/surveys", headers=ADMIN, json=paper_body(*trees))
    assert survey.status_code == 201, survey.text
    [respondent] = invite_respondents(client, survey.json()["id"])
    roles = role_headers | {
        "respondent": respondent.headers,
        "evaluator": evaluator_headers(client),
    }
    return {scheme: roles[role] for scheme, role in SCHEME_ROLES.items()}


def conformance_failures(
    operation: Any, role_headers: dict[str, dict[str, str]], calls: list[int]
) -> str | None:
    """Run one operation's valid and invalid examples as both roles; the failure, if any.
    Appends the number of requests made to ``calls``."""
    cases = st.one_of(
        operation.as_strategy(mode) for mode in (GenerationMode.POSITIVE, GenerationMode.NEGATIVE)
    )
    calls.append(0)

    @given(case=cases)
    @settings(
        max_examples=EXAMPLES,
        derandomize=True,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
        phases=[Phase.explicit, Phase.generate],
    )
    def run(case: Any) -> None:
        # A case whose headers break the schema (Authorization left out, say) is no negative
        # case once each role's real credentials replace them: skipped, not sent.
        header = case.meta.components.get(ParameterLocation.HEADER) if case.meta else None
        assume(header is None or header.mode is not GenerationMode.NEGATIVE)
        for headers in role_headers.values():
            calls[-1] += 1
            case.call_and_validate(headers=headers, checks=CHECKS)

    try:
        run()
    except (Exception, BaseExceptionGroup) as exc:  # says what failed and how to reproduce
        return f"{operation.label}: {exc}"
    return None


def coverage_failures(
    operation: Any, scheme_headers: dict[str, dict[str, str]], calls: list[int]
) -> str | None:
    """Send every negative coverage-phase case of one operation (each schema violation) with
    the credentials it asks for; the first failure, if any."""
    schemes = [
        name for requirement in operation.definition.raw.get("security", []) for name in requirement
    ]
    headers = scheme_headers[schemes[0]] if schemes else {}
    generator = CoverageGenerator(
        operation=operation,
        generation_modes=[GenerationMode.NEGATIVE],
        generation_config=operation.schema.config.generation_for(
            operation=operation, phase="coverage"
        ),
        auth_storage=None,
        override=Override(),
        feedback=FeedbackSources(),
    )
    calls.append(0)
    for case in generator:
        calls[-1] += 1
        try:
            case.call_and_validate(headers=headers, checks=CHECKS)
        except (Exception, BaseExceptionGroup) as exc:
            return f"{operation.label} ({case.meta.phase.data.description}): {exc}"
    return None


def test_every_schema_violation_is_refused(api_schema, scheme_headers) -> None:
    operations = [result.ok() for result in api_schema.get_all_operations()]
    calls: list[int] = []
    failures = [f for op in operations if (f := coverage_failures(op, scheme_headers, calls))]
    print(
        f"schemathesis coverage: {len(operations)} operations, {sum(calls)} requests, "
        f"{len(failures)} failing"
    )
    assert failures == [], "\n\n".join(failures)
    assert min(calls) > 0


def test_every_operation_conforms_to_the_schema(api_schema, role_headers) -> None:
    operations = [result.ok() for result in api_schema.get_all_operations()]
    assert len(operations) >= 20
    calls: list[int] = []
    failures = [f for op in operations if (f := conformance_failures(op, role_headers, calls))]
    print(
        f"schemathesis: {len(operations)} operations, {sum(calls)} requests, "
        f"{len(failures)} failing"
    )
    assert failures == [], "\n\n".join(failures)
    assert min(calls) > 0
