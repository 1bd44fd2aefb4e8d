"""No request produces a 500: arbitrary bodies, ids and headers get JSON 4xx answers."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given
from hypothesis import settings as hypothesis_settings
from hypothesis import strategies as st

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)
label_bodies = json_values | st.fixed_dictionaries(
    {"winner": st.integers(-(2**70), 2**70) | json_values},
    optional={"response_ms": st.integers(-(2**70), 2**70) | json_values},
)
study_bodies = json_values | st.fixed_dictionaries(
    {"name": st.text(max_size=300), "n_candidates": st.integers(-5, 300) | json_values},
    optional={
        "env_id": st.sampled_from(["Hopper-v5", "Nope-v0", "", "CartPole-v1"]),
        "p": st.floats() | json_values,
        "seed": st.integers(-(2**70), 2**70),
        "sampling": st.text(max_size=10),
        "instructions": json_values,
    },
)
path_ids = st.integers(-(2**70), 2**70).map(str) | st.text(
    st.characters(min_codepoint=33, max_codepoint=126, exclude_characters="/?#%"),
    min_size=1,
    max_size=12,
)

fuzz = hypothesis_settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@pytest.fixture(scope="module")
def player_headers(client, admin, study) -> dict[str, str]:
    token = client.post(f"/api/studies/{study['id']}/participants", headers=admin).json()["token"]
    return {"Authorization": f"Bearer {token}"}


def _post(client, path: str, body, headers: dict[str, str]):
    """POST ``body`` as JSON text; NaN and infinities as Python writes them."""
    return client.post(
        path,
        content=json.dumps(body).encode(),
        headers=headers | {"Content-Type": "application/json"},
    )


def _assert_clean(response) -> None:
    assert response.status_code < 500, response.text
    if response.status_code >= 400:
        assert "detail" in response.json()


@fuzz
@given(match_id=path_ids, body=label_bodies)
def test_label_endpoint_never_fails(client, player_headers, match_id: str, body) -> None:
    _assert_clean(_post(client, f"/api/matches/{match_id}/label", body, player_headers))


@fuzz
@given(body=study_bodies)
def test_study_creation_never_fails(client, admin, body) -> None:
    if isinstance(body, dict) and isinstance(body.get("n_candidates"), int):
        body["n_candidates"] = min(body["n_candidates"], 3)  # keep accepted studies small
    _assert_clean(_post(client, "/api/studies", body, admin))


@fuzz
@given(study_id=path_ids, candidate_id=path_ids, participant_id=path_ids)
def test_id_paths_never_fail(
    client, admin, study_id: str, candidate_id: str, participant_id: str
) -> None:
    for path in (
        f"/api/studies/{study_id}",
        f"/api/studies/{study_id}/candidates",
        f"/api/studies/{study_id}/candidates/{candidate_id}/image",
        f"/api/participants/{participant_id}/tree",
        f"/api/studies/{study_id}/labels.csv",
    ):
        _assert_clean(client.get(path, headers=admin))
