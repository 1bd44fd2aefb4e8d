"""The OpenAPI document states the rules the server enforces (issue 24): a pool of at least
two ``participant_ids``, and ``redirect_url`` an http(s) URL; on SQLite and PostgreSQL."""

from __future__ import annotations

import re
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.web import ADMIN


def _field(client: TestClient, model: str, name: str) -> dict[str, Any]:
    """The schema of ``model.name``, the ``null`` alternative of an optional one left out."""
    prop = client.app.openapi()["components"]["schemas"][model]["properties"][name]
    [schema] = [s for s in prop.get("anyOf", [prop]) if s.get("type") != "null"]
    return schema


def test_participant_ids_documents_at_least_two(client: TestClient, study) -> None:
    assert _field(client, "RunCreate", "participant_ids")["minItems"] == 2
    for ids in ([], [1]):
        body = {"study_id": study["id"], "algo": "ppo", "timesteps": 1000, "participant_ids": ids}
        response = client.post("/api/runs", json=body, headers=ADMIN)
        assert response.status_code == 422, response.text


URLS = [
    "https://example.org/done?cc=C0DE",
    "HTTP://example.org",
    "http://x",
    "javascript:alert(1)",
    "ftp://example.org",
    "http:example.org",
    "http://",
    "https://a b",
    " https://example.org",
    "data:text/html,hi",
    "//example.org",
]


@pytest.mark.parametrize("model", ["CrowdIn", "OpenLinkIn"])
def test_redirect_url_pattern_is_the_servers_rule(client: TestClient, study, model) -> None:
    pattern = _field(client, model, "redirect_url")["pattern"]
    settings = {"enabled": True, "max_participants": 50}
    for url in URLS:
        response = client.put(
            f"/api/studies/{study['id']}/crowd",
            json=settings | {"redirect_url": url},
            headers=ADMIN,
        )
        assert response.status_code == (200 if re.search(pattern, url) else 422), url
    assert not re.search(pattern, "javascript:alert(1)")
