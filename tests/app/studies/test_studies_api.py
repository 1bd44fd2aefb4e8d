"""Researcher API: studies, candidates, images, invitations; auth and bad input."""

from __future__ import annotations

import io

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image

from app.main import create_app
from app.runtime import Runtime
from app.studies.service import StudySpec, create_study
from engine.bracket import make_first_round
from engine.candidates import sample_candidates
from tests.support.studies import wait_ready


def test_healthz(client) -> None:
    assert client.get("/healthz").json() == {"status": "ok"}


def test_openapi_lists_the_required_paths(client) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    for path in (
        "/api/studies",
        "/api/studies/{study_id}",
        "/api/studies/{study_id}/candidates",
        "/api/studies/{study_id}/participants",
        "/api/participants/me/next-match",
        "/api/matches/{match_id}/label",
        "/api/participants/{participant_id}/tree",
        "/healthz",
    ):
        assert path in paths
    assert client.get("/docs").status_code == 200


def test_created_study_is_listed_and_ready(client, admin, study) -> None:
    listed = client.get("/api/studies", headers=admin).json()
    assert study["id"] in [s["id"] for s in listed]
    got = client.get(f"/api/studies/{study['id']}", headers=admin).json()
    assert got == study
    assert (got["status"], got["env_id"], got["n_candidates"], got["error"]) == (
        "ready",
        "Hopper-v5",
        5,
        None,
    )
    assert got["created_at"].endswith("Z")


def test_post_answers_at_once_with_preparing_or_ready(client, admin) -> None:
    body = {
        "name": "fast",
        "env_id": "Hopper-v5",
        "n_candidates": 2,
        "p": 0.5,
        "seed": 1,
        "sampling": "uniform",
        "instructions": "",
    }
    created = client.post("/api/studies", json=body, headers=admin)
    assert created.status_code == 201
    assert created.json()["status"] in ("preparing", "ready")
    assert {k: created.json()[k] for k in body} == body


def test_candidates_and_bracket_match_the_engine_for_the_seed(client, admin, study, invite) -> None:
    got = client.get(f"/api/studies/{study['id']}/candidates", headers=admin).json()
    rng = np.random.default_rng(study["seed"])
    expected = sample_candidates("Hopper-v5", 5, rng=rng, mode="uniform")
    assert [c["id"] for c in got] == [0, 1, 2, 3, 4]
    for c, e in zip(got, expected, strict=True):
        assert c["qpos"] == e.qpos.tolist() and c["qvel"] == e.qvel.tolist()  # exact floats
        assert c["env_reward"] == e.env_reward
        assert c["image_url"] == f"/api/studies/{study['id']}/candidates/{c['id']}/image"
    first = make_first_round(
        [c.id for c in expected], np.array([c.env_reward for c in expected]), 0.9, rng
    )
    assert sum(b is None for _, b in first) == 3  # five players: three byes
    rounds = client.get("/api/participants/me/bracket", headers=invite().headers).json()["rounds"]
    assert [(c["a"], c["b"]) for c in rounds[0]] == first


@pytest.mark.parametrize(("size", "pixels"), [("full", 480), ("thumb", 160)])
def test_candidate_images_are_jpegs(client, admin, study, size: str, pixels: int) -> None:
    response = client.get(
        f"/api/studies/{study['id']}/candidates/4/image?size={size}", headers=admin
    )
    assert response.status_code == 200
    assert response.headers["content-type"] == "image/jpeg"
    assert Image.open(io.BytesIO(response.content)).size == (pixels, pixels)


@pytest.mark.parametrize(
    "path",
    [
        "/api/studies/{sid}/candidates/5/image",  # N = 5: ids 0..4
        "/api/studies/999999/candidates/0/image",
        "/api/studies/999999",
        "/api/studies/999999/candidates",
    ],
)
def test_unknown_ids_are_404(client, admin, study, path: str) -> None:
    response = client.get(path.format(sid=study["id"]), headers=admin)
    assert response.status_code == 404
    assert "not found" in response.json()["detail"]


@pytest.mark.parametrize(
    "path",
    [
        "/api/studies/abc",
        "/api/studies/0",
        "/api/studies/99999999999999999999",
        "/api/studies/{sid}/candidates/-1/image",
        "/api/studies/{sid}/candidates/..%2f..%2fx/image",
        "/api/studies/{sid}/candidates/1/image?size=huge",
    ],
)
def test_malformed_ids_are_422(client, admin, study, path: str) -> None:
    response = client.get(path.format(sid=study["id"]), headers=admin)
    assert response.status_code in (404, 422)
    assert "detail" in response.json()


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"n_candidates": 1}, "n_candidates"),
        ({"n_candidates": 129}, "n_candidates"),
        ({"p": 1.5}, "p"),
        ({"p": -0.1}, "p"),
        ({"seed": -1}, "seed"),
        ({"sampling": "clever"}, "sampling"),
        ({"name": ""}, "name"),
        ({"env_id": "NoSuchEnv-v0"}, "unknown env"),
        ({"env_id": "CartPole-v1"}, "not a MuJoCo"),
        ({"extra": 1}, "extra"),
        ({"n_candidates": "many"}, "n_candidates"),
    ],
)
def test_bad_study_bodies_are_422(client, admin, change: dict, needle: str) -> None:
    body = {"name": "x", "env_id": "Hopper-v5", "n_candidates": 4} | change
    response = client.post("/api/studies", json=body, headers=admin)
    assert response.status_code == 422
    assert needle in str(response.json()["detail"])


def test_body_that_is_not_json_is_422(client, admin) -> None:
    response = client.post(
        "/api/studies", content=b"{nope", headers=admin | {"Content-Type": "application/json"}
    )
    assert response.status_code == 422


@pytest.mark.parametrize(
    "headers",
    [
        {},
        {"Authorization": "Bearer wrong"},
        {"Authorization": "Basic dGVzdA=="},
        {"Authorization": "Bearer \u00e9\u00e9".encode("latin-1")},
        {"Cookie": "acv_researcher=forged"},
    ],
)
def test_researcher_endpoints_need_the_admin_token(client, study, headers) -> None:
    for method, path in [
        ("GET", "/api/studies"),
        ("GET", f"/api/studies/{study['id']}"),
        ("POST", f"/api/studies/{study['id']}/participants"),
        ("GET", f"/api/studies/{study['id']}/labels.csv"),
    ]:
        response = client.request(method, path, headers=headers)
        assert response.status_code == 401, (method, path)
        assert response.headers["www-authenticate"] == "Bearer"


def test_participant_token_is_not_a_researcher_token(client, study, invite) -> None:
    player = invite()
    assert client.get("/api/studies", headers=player.headers).status_code == 401


def test_researcher_cookie_from_services_is_accepted(client, study) -> None:
    from app.core.auth import RESEARCHER_COOKIE, researcher_cookie_value

    cookie = researcher_cookie_value(admin_token=client.app.state.runtime.admin_token)
    response = client.get("/api/studies", headers={"Cookie": f"{RESEARCHER_COOKIE}={cookie}"})
    assert response.status_code == 200


def test_invite_one_and_many(client, admin, study) -> None:
    one = client.post(
        f"/api/studies/{study['id']}/participants", headers=admin, json={"name": "Ada"}
    )
    assert one.status_code == 201
    body = one.json()
    assert set(body) >= {"id", "token", "invite_url"}
    assert body["invite_url"] == f"http://testserver/p/{body['token']}"
    many = client.post(
        f"/api/studies/{study['id']}/participants/batch", headers=admin, json={"count": 3}
    )
    assert many.status_code == 201 and len(many.json()) == 3
    tokens = {p["token"] for p in many.json()} | {body["token"]}
    assert len(tokens) == 4
    listed = client.get(f"/api/studies/{study['id']}/participants", headers=admin).json()
    mine = {p["id"]: p for p in listed}[body["id"]]
    assert (mine["name"], mine["progress"], mine["finished"]) == (
        "Ada",
        {"done": 0, "total": 4},
        False,
    )


@pytest.mark.parametrize("count", [0, 501, -3])
def test_bad_batch_sizes_are_422(client, admin, study, count: int) -> None:
    response = client.post(
        f"/api/studies/{study['id']}/participants/batch", headers=admin, json={"count": count}
    )
    assert response.status_code == 422


def test_cannot_invite_to_unknown_study(client, admin) -> None:
    response = client.post("/api/studies/424242/participants", headers=admin)
    assert response.status_code == 404


def test_failed_preparation_is_reported_not_raised(client, admin, make_study, monkeypatch) -> None:
    def broken(*_args, **_kwargs):
        raise RuntimeError("no OpenGL here\nsecond line")

    monkeypatch.setattr("app.studies.service.render_candidates", broken)
    failed = make_study(n_candidates=3)
    assert (failed["status"], failed["error"]) == ("failed", "RuntimeError: no OpenGL here")
    refused = client.post(f"/api/studies/{failed['id']}/participants", headers=admin)
    assert refused.status_code == 409 and "failed" in refused.json()["detail"]
    assert client.get(f"/api/studies/{failed['id']}/candidates", headers=admin).json() == []


def test_a_restart_finishes_studies_left_preparing(settings, admin) -> None:
    runtime = Runtime(settings)  # stored, then "crashed" before preparing it
    with runtime.sessions() as session:
        left = create_study(session, spec=StudySpec("interrupted", "Hopper-v5", 2, 0.5, seed=9))
    runtime.close()
    with TestClient(create_app(settings)) as restarted:
        body = wait_ready(restarted, left.id)
    assert body["status"] == "ready"
