"""Policies from elsewhere through the API (issue 44 §2): an external experiment, imports of
ONNX policies into its arms, and every refusal a 4xx naming its rule with nothing stored.

No policy is judged here (the run worker is off): judging is tests/app/runs/test_agents_judged.py.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from app.models import Experiment, Run
from app.runs import agent_import, agents_api
from tests.support.agents import (
    DECLARED,
    create_external,
    external_data,
    forbidden_op,
    obs_norm,
    policy,
    sb3_zip,
    stored_files,
    upload,
    with_metadata,
    wrong_sizes,
)
from tests.support.runs import run_app
from tests.support.studies import new_study
from tests.support.web import ADMIN

# postgres_only: training is the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client, seed=5)


@pytest.fixture(scope="module")
def external(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    return create_external(client, study["id"], seeds=2)


def _runs_root(client: TestClient) -> Path:
    state = client.app.state
    return state.job_settings.runs_root(state.runtime.settings)


def _n_runs(client: TestClient) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(select(func.count()).select_from(Run))


def test_an_external_experiment_freezes_its_advice_and_trains_nothing(
    client: TestClient, external: dict[str, Any]
) -> None:
    spec = external["spec"]
    assert spec["external"] is True and spec["teacher"] == "good"
    assert spec["env_id"] == "Hopper-v5" and (spec["obs_dim"], spec["act_dim"]) == (11, 3)
    assert re.fullmatch(r"[0-9a-f]{64}", spec["tree_sha256"]) and "frozen" not in spec
    assert external["runs"] == [] and external["seeds"] == [] == external["pilot_seeds"]
    again = client.get(f"/api/experiments/{external['id']}", headers=ADMIN).json()
    assert again["spec"] == spec
    shaped = client.get(f"/api/experiments/{external['id']}/verdict?judge=shaped", headers=ADMIN)
    assert shaped.status_code == 422 and "return or behaviour only" in shaped.json()["detail"]
    pending = client.get(f"/api/experiments/{external['id']}/verdict", headers=ADMIN)
    assert pending.status_code == 202


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ({}, "give participant_id"),
        ({"teacher": "good", "seeds": 1}, "seeds"),
        ({"teacher": "good", "seeds": True}, "seeds"),
        ({"teacher": "nobody"}, "teacher"),
        ({"teacher": "good", "participant_id": 1}, "one advice source"),
    ],
)
def test_bad_external_experiments_are_refused(
    client: TestClient, study: dict[str, Any], body: dict[str, Any], says: str
) -> None:
    response = client.post(
        "/api/experiments/external", json={"study_id": study["id"], **body}, headers=ADMIN
    )
    assert response.status_code == 422, response.text
    assert says in str(response.json()["detail"])


def test_policies_are_stored_once_by_hash_and_queued_in_their_arms(
    client: TestClient, study: dict[str, Any]
) -> None:
    experiment = create_external(client, study["id"], seeds=2)
    eid, tree = experiment["id"], experiment["spec"]["tree_sha256"]
    model = policy(seed=1)
    advised = upload(client, eid, model, arm="advised", seed=0, tree_sha256=tree, **DECLARED)
    assert advised.status_code == 202, advised.text
    run = advised.json()
    assert (run["status"], run["algo"], run["seed"], run["timesteps"]) == (
        "queued",
        "ppo-shaped",
        0,
        100000,
    )
    imported = run["imported"]
    assert imported["arm"] == "advised" and imported["tree_matches"] is True
    assert imported["declared"] == {
        "algorithm": "sb3 PPO",
        "steps": 100000,
        "seed": 0,
        "tree_sha256": tree,
    }
    assert imported["note"] == "ACV did not see them train"
    stored = _runs_root(client) / "policies" / f"{imported['onnx_sha256']}.onnx"
    assert stored.read_bytes() == model  # the file as uploaded, named by its hash
    baseline = upload(
        client, eid, policy(seed=2), norm=obs_norm(), arm="baseline", seed=0, **DECLARED
    )
    assert baseline.status_code == 202, baseline.text
    assert baseline.json()["algo"] == "ppo"
    assert baseline.json()["imported"]["obs_norm_sha256"] is not None
    pilot = upload(client, eid, policy(seed=3), arm="pilot", seed=100, **DECLARED)
    assert pilot.status_code == 202, pilot.text
    shown = client.get(f"/api/experiments/{eid}", headers=ADMIN).json()
    assert shown["seeds"] == [0] and shown["pilot_seeds"] == [100]
    assert [(r["role"], r["imported"]["arm"]) for r in shown["runs"]] == [
        ("advised", "advised"),
        ("baseline", "baseline"),
        ("pilot", "pilot"),
    ]
    before, files = _n_runs(client), stored_files(_runs_root(client))
    advised_form = {"arm": "advised", "tree_sha256": tree, **DECLARED}
    refusals = [
        (upload(client, eid, model, seed=1, **advised_form), 409, "already"),
        (upload(client, eid, policy(seed=4), seed=0, **advised_form), 409, "seed 0 already"),
        (upload(client, eid, policy(5), arm="pilot", seed=0, **DECLARED), 422, "evaluation seed"),
        (upload(client, eid, policy(6), arm="baseline", seed=100, **DECLARED), 422, "pilot seed"),
    ]
    for response, status, says in refusals:
        assert response.status_code == status, response.text
        assert says in response.json()["detail"]
    assert (
        upload(
            client, eid, policy(7), arm="advised", seed=1, tree_sha256=tree, **DECLARED
        ).status_code
        == 202
    )
    full = upload(client, eid, policy(8), arm="advised", seed=2, tree_sha256=tree, **DECLARED)
    assert full.status_code == 409 and "is full: it takes 2 policies" in full.json()["detail"]
    assert _n_runs(client) == before + 1
    assert len(stored_files(_runs_root(client))) == len(files) + 1


def test_declared_settings_come_from_the_model_s_metadata_when_not_given(
    client: TestClient, external: dict[str, Any]
) -> None:
    model = with_metadata(policy(seed=11), algorithm="acv ppo", timesteps="4096", seed="7")
    response = upload(client, external["id"], model, arm="baseline")
    assert response.status_code == 202, response.text
    declared = response.json()["imported"]["declared"]
    assert declared == {"algorithm": "acv ppo", "steps": 4096, "seed": 7, "tree_sha256": None}
    assert response.json()["imported"]["metadata"]["timesteps"] == "4096"


@pytest.mark.parametrize(
    ("model", "fields", "status", "says"),
    [
        (b"not an onnx model at all", {}, 422, "not an ONNX model"),
        (policy()[:60], {}, 422, "not an ONNX model"),
        (forbidden_op(), {}, 422, "uses op 'Exp', which is not allowed"),
        (external_data(), {}, 422, "has external data"),
        (wrong_sizes(), {}, 422, "not float32 [N, obs_dim=11]"),
        (policy(env_id=None), {}, 422, "no env id"),
        (policy(env_id="Walker2d-v5"), {}, 422, "the policy is for Walker2d-v5, but"),
        (policy(env_id=None), {"env_id": "HalfCheetah-v5"}, 422, "the policy is for HalfCheetah"),
        (policy(), {"env_id": "Walker2d-v5"}, 422, "but 'Walker2d-v5' was given"),
        (sb3_zip(), {}, 415, "not an ONNX model: the API stores ONNX only"),
        (policy(), {"arm": "champion"}, 422, "arm"),
        (policy(), {"seed": "1.0"}, 422, "seed"),
        (policy(), {"seed": "true"}, 422, "seed"),
        (policy(), {"steps": "0"}, 422, "steps"),
        (policy(), {"algorithm": None}, 422, "no declared algorithm"),
        (policy(), {"tree_sha256": "abc"}, 422, "tree_sha256"),
        (policy(), {"arm": "advised"}, 422, "declares the tree it trained with"),
        (policy(), {"tree_sha256": "a" * 64}, 422, "trains without advice"),
    ],
)
def test_bad_policies_are_refused_and_nothing_is_stored(
    client: TestClient,
    external: dict[str, Any],
    model: bytes,
    fields: dict[str, Any],
    status: int,
    says: str,
) -> None:
    before, files = _n_runs(client), stored_files(_runs_root(client))
    form = {"arm": "baseline", "seed": 50, **DECLARED, **fields}
    response = upload(client, external["id"], model, **form)
    assert response.status_code == status, response.text
    assert says in str(response.json()["detail"])
    assert _n_runs(client) == before and stored_files(_runs_root(client)) == files


def test_a_bad_normalisation_is_refused(client: TestClient, external: dict[str, Any]) -> None:
    before = _n_runs(client)
    for norm, says in [
        (obs_norm(17), "mean is float64 (17,)"),
        (b"PK\x03\x04no", "not a readable"),
    ]:
        response = upload(
            client, external["id"], policy(21), norm=norm, arm="baseline", seed=60, **DECLARED
        )
        assert response.status_code == 422 and says in response.json()["detail"], response.text
    assert _n_runs(client) == before


def test_a_file_over_its_cap_is_refused(
    client: TestClient, external: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(agents_api, "MAX_MODEL_BYTES", 1000)
    before = _n_runs(client)
    response = upload(client, external["id"], policy(), arm="baseline", seed=70, **DECLARED)
    assert response.status_code == 413, response.text
    assert "the model file is" in response.json()["detail"] and "limit of 1000" in response.text
    assert _n_runs(client) == before


def test_a_huge_body_is_refused_unread(client: TestClient, external: dict[str, Any]) -> None:
    """A declared length over the route's limit is refused before a byte is read; any other
    route keeps the API's usual limit."""
    huge = str(agents_api.MAX_UPLOAD_BYTES + 1)
    headers = ADMIN | {"content-length": huge, "content-type": "multipart/form-data; boundary=x"}
    response = client.post(
        f"/api/experiments/{external['id']}/agents", content=b"--x", headers=headers
    )
    assert response.status_code == 413
    assert (
        response.json()["detail"]
        == f"the request body is larger than {agents_api.MAX_UPLOAD_BYTES} bytes"
    )
    chunks = lambda: (b"x" * (1 << 20) for _ in range(2))  # noqa: E731  # chunked, 2 MiB
    streamed = client.post(
        f"/api/experiments/{external['id']}/agents",
        content=chunks(),
        headers=ADMIN | {"content-type": "multipart/form-data; boundary=x"},
    )
    assert streamed.status_code == 400, streamed.text  # parsed, not refused: under its limit
    refused = client.post("/api/studies", content=chunks(), headers=ADMIN)
    assert refused.status_code == 413 and "larger than 1048576 bytes" in refused.text
    big = b"x" * (2 << 20)  # under the upload limit, over everyone else's
    other = client.post(
        "/api/studies", content=big, headers=ADMIN | {"content-type": "application/json"}
    )
    assert other.status_code == 413 and "larger than 1048576 bytes" in other.text


def test_only_external_experiments_take_policies(client: TestClient, study: dict[str, Any]) -> None:
    body = {"study_id": study["id"], "teacher": "good", "timesteps": 512, "n_envs": 1}
    own = client.post("/api/experiments", json=body | {"seeds": 2, "pilot_seeds": 1}, headers=ADMIN)
    assert own.status_code == 202, own.text
    before = _n_runs(client)
    response = upload(client, own.json()["id"], policy(), arm="baseline", seed=0, **DECLARED)
    assert response.status_code == 409 and "trains its own runs" in response.json()["detail"]
    missing = upload(client, 999_999, policy(), arm="baseline", seed=0, **DECLARED)
    assert missing.status_code == 404
    anonymous = upload(client, own.json()["id"], policy(), headers={}, arm="baseline", seed=0)
    assert anonymous.status_code == 401
    assert _n_runs(client) == before


def test_the_advice_tree_downloads_with_its_hash(
    client: TestClient, study: dict[str, Any], external: dict[str, Any]
) -> None:
    import gymnasium as gym

    from engine.envs import make_env
    from engine.rl.shaping import AdviceWrapper

    response = client.get(f"/api/experiments/{external['id']}/advice-tree", headers=ADMIN)
    assert response.status_code == 200, response.text
    digest = external["spec"]["tree_sha256"]
    assert hashlib.sha256(response.content).hexdigest() == digest  # sha256sum of the file
    assert response.headers["x-tree-sha256"] == digest
    assert response.headers["etag"] == f'"{digest}"'
    assert response.headers["content-type"].startswith("application/json")
    env: gym.Env[Any, Any] = AdviceWrapper(make_env("Hopper-v5"), response.json(), scale=10.0)
    env.reset(seed=0)
    *_, info = env.step(env.action_space.sample())
    assert {"R", "F"} <= set(info)
    env.close()
    missing = client.get("/api/experiments/999999/advice-tree", headers=ADMIN)
    assert missing.status_code == 404 and "detail" in missing.json()
    assert client.get(f"/api/experiments/{external['id']}/advice-tree").status_code == 401
    body = {"study_id": study["id"], "teacher": "good", "timesteps": 512, "n_envs": 1}
    own = client.post("/api/experiments", json=body | {"seeds": 2}, headers=ADMIN).json()
    advised = next(r["id"] for r in own["runs"] if r["role"] == "advised")
    tree = client.get(f"/api/experiments/{own['id']}/advice-tree", headers=ADMIN)
    assert tree.status_code == 200
    assert tree.json() == client.get(f"/api/runs/{advised}/advice-tree", headers=ADMIN).json()
    assert tree.headers["x-tree-sha256"] == hashlib.sha256(tree.content).hexdigest()


def test_a_refused_import_keeps_the_file_that_another_run_names(
    client: TestClient, study: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same policy sent twice at once (a double click): the request that wrote the file
    loses the seed to the other, whose run names that file; the file stays (it was deleted)."""
    experiment = create_external(client, study["id"], seeds=2)
    model, real = policy(91), agent_import._store

    def other_request_first(session: Any, held: Any, *args: Any) -> Any:
        with client.app.state.runtime.sessions() as other:  # it stores the same seed first
            real(other, other.get_one(Experiment, held.id), *args)
        return real(session, held, *args)

    monkeypatch.setattr(agent_import, "_store", other_request_first)
    refused = upload(client, experiment["id"], model, arm="baseline", seed=70, **DECLARED)
    assert refused.status_code == 409, refused.text
    digest = hashlib.sha256(model).hexdigest()
    assert f"{digest}.onnx" in stored_files(_runs_root(client))
