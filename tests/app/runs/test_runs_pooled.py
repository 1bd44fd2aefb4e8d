"""Pooled advice through ``/api/runs``: a run on several finished participants' trees (chosen,
or all of the study's), its bad requests, its training on the pool, and the agent against each
participant at every checkpoint (stored by the executor, read by ``/advisors`` and the
checkpoint report). On PostgreSQL only (``postgres_only``: training is the subject).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.db import make_engine, make_sessions
from app.runs import artefacts
from app.runs import service as runs
from engine.conformance import compare
from engine.judges import JUDGES
from engine.pooling import pooled_tree
from engine.rl.runner import load_run_pool
from engine.treefile import tree_from_json, tree_to_json
from tests.support.runs import TINY, create_run, finished_participant, run_app, wait_run
from tests.support.studies import Player, new_study
from tests.support.web import ADMIN, audit, csrf_token, logged_in

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client)


@pytest.fixture(scope="module")
def people(client: TestClient, study: dict[str, Any]) -> list[int]:
    """Three finished participants: two pick side a, one side b (so their trees differ)."""
    ids = [finished_participant(client, study["id"]) for _ in range(2)]
    body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    Player(client, body["id"], body["token"], body["invite_url"]).play(
        lambda m: m["b"]["candidate_id"]
    )
    return [*ids, body["id"]]


@pytest.fixture(scope="module")
def pooled(client: TestClient, study: dict, people: list[int]) -> dict[str, Any]:
    """A finished ``bipars-em`` run on the pool of the last two participants (given in reverse
    order: the pool is kept by increasing id)."""
    run_id = create_run(
        client,
        study_id=study["id"],
        participant_ids=[people[2], people[1]],
        algo="bipars-em",
        timesteps=256,
        checkpoint_every=128,
        **TINY,
    )
    return wait_run(client, run_id)


def api(client: TestClient, path: str, status: int = 200) -> Any:
    response = client.get(path, headers=ADMIN)
    assert response.status_code == status, response.text
    return response.json()


def test_a_pooled_run_trains_on_the_pool_and_compares_with_the_pooled_verdict(
    client: TestClient, settings, people: list[int], pooled: dict[str, Any]
) -> None:
    assert pooled["status"] == "succeeded", pooled
    assert pooled["participant_ids"] == people[1:] and pooled["participant_id"] is None
    assert pooled["teacher"] is None
    assert pooled["advice"] == f"2 participants pooled (#{people[1]}, #{people[2]})"
    trees = [tree_from_json(api(client, f"/api/participants/{p}/tree")) for p in people[1:]]
    on_disk = load_run_pool(settings.data_dir / "runs" / str(pooled["id"]))
    assert [tree_to_json(t) for t in on_disk] == [tree_to_json(t) for t in trees]
    verdict = api(client, f"/api/runs/{pooled['id']}/advice-tree")
    assert verdict == tree_to_json(pooled_tree(trees))


def test_the_artefact_holds_the_agent_against_each_participant(
    client: TestClient, settings, people: list[int], pooled: dict[str, Any]
) -> None:
    run_id = pooled["id"]
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            stored = artefacts.payloads(session, run_id=run_id)
    finally:
        engine.dispose()
    assert list(stored) == [128, 256]
    body = stored[256]
    assert [a["participant_id"] for a in body["advisors"]] == people[1:]
    for advisor in body["advisors"]:
        tree = tree_from_json(api(client, f"/api/participants/{advisor['participant_id']}/tree"))
        assert set(advisor["judges"]) == set(JUDGES)
        for judge, got in advisor["judges"].items():
            agent = tree_from_json(body["judges"][judge]["tree"])
            assert got == compare(tree, agent).to_json()


def test_the_advisors_endpoint_and_the_checkpoint_report(
    client: TestClient, people: list[int], pooled: dict[str, Any]
) -> None:
    run_id = pooled["id"]
    got = api(client, f"/api/runs/{run_id}/advisors?judge=value&checkpoint=128")
    assert got["checkpoint"] == 128 and got["judge"] == "shaped-value"  # value: the old name
    assert [a["participant_id"] for a in got["advisors"]] == people[1:]
    assert got["pooled"] == api(
        client, f"/api/runs/{run_id}/conformance?judge=value&checkpoint=128"
    )
    report = api(client, f"/api/runs/{run_id}/checkpoint-report?judge=value&checkpoint=128")
    assert report["advisors"] == got["advisors"]
    assert "the pool's advice" in report["verdict"] or "the pool's choices" in report["verdict"]


def test_all_participants_pools_every_finished_one(
    client: TestClient, study: dict, people: list[int]
) -> None:
    body = {"study_id": study["id"], "all_participants": True, "algo": "ppo", "timesteps": 128}
    run_id = create_run(client, **body, **TINY)
    run = wait_run(client, run_id)
    assert run["participant_ids"] == sorted(people) and run["status"] == "succeeded"
    assert run["advice"].startswith("3 participants pooled (")
    assert api(client, f"/api/runs/{run_id}/advisors")["advisors"]


def test_runs_on_the_same_pool_are_the_same_advice(
    client: TestClient, settings, study: dict, people: list[int], pooled: dict[str, Any]
) -> None:
    """The multi-run comparison puts a pool's runs together, and nothing else with them."""
    body = {"study_id": study["id"], "algo": "ppo", "timesteps": 128, **TINY}
    same = create_run(client, participant_ids=people[1:], **body)
    other = create_run(client, participant_ids=people[:2], **body)
    single = create_run(client, participant_id=people[1], **body)
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            run = runs.get_run(session, run_id=pooled["id"])
            ids = [r.id for r in runs.same_advice_runs(session, run=run)]
    finally:
        engine.dispose()
    assert pooled["id"] in ids and same in ids and other not in ids and single not in ids
    for run_id in (same, other, single):
        assert wait_run(client, run_id)["status"] == "succeeded"


def test_a_run_on_one_participant_has_no_advisors(
    client: TestClient, study: dict, people: list[int]
) -> None:
    run_id = create_run(
        client, study_id=study["id"], participant_id=people[0], algo="ppo", timesteps=128, **TINY
    )
    wait_run(client, run_id)
    response = client.get(f"/api/runs/{run_id}/advisors", headers=ADMIN)
    assert response.status_code == 409 and "not trained on pooled" in response.json()["detail"]
    assert api(client, f"/api/runs/{run_id}/checkpoint-report")["advisors"] is None


@pytest.mark.parametrize(
    ("change", "status", "words"),
    [
        ({"participant_ids": "one"}, 422, "participant_ids"),
        ({"participant_ids": "duplicate"}, 422, "more than once"),
        ({"participant_ids": "unfinished"}, 409, "not finished"),
        ({"participant_ids": "elsewhere"}, 404, "not in study"),
        ({"participant_ids": "pair", "teacher": "standing"}, 422, "not both"),
        ({"participant_ids": "pair", "participant_id": 0}, 422, "not both"),
        ({"participant_ids": "pair", "all_participants": True}, 422, "not both"),
        ({"all_participants": 1}, 422, "all_participants"),
        ({"participant_ids": [True, 2]}, 422, "participant_ids"),
        ({"participant_ids": 999999}, 404, "participant 999999"),
    ],
)
def test_bad_pools(
    client: TestClient, study: dict, people: list[int], change: dict, status: int, words: str
) -> None:
    lists = {
        "one": [people[0]],
        "duplicate": [people[0], people[1], people[0]],
        "pair": people[:2],
        "unfinished": [people[0], _invited(client, study["id"])],
        "elsewhere": [people[0], _other_studys_participant(client)],
    }
    body = {"study_id": study["id"], "algo": "ppo", "timesteps": 1000, **change}
    if isinstance(body.get("participant_ids"), str):
        body["participant_ids"] = lists[body["participant_ids"]]
    elif body.get("participant_ids") == 999999:
        body["participant_ids"] = [people[0], 999999]
    if body.get("participant_id") == 0:
        body["participant_id"] = people[2]
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == status, response.text
    assert words in str(response.json()["detail"])


def test_all_participants_needs_two_finished(client: TestClient) -> None:
    other = new_study(client, seed=5)
    finished_participant(client, other["id"])
    body = {"study_id": other["id"], "all_participants": True, "timesteps": 1000}
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == 409 and "1 finished participant" in response.json()["detail"]


def _invited(client: TestClient, study_id: int) -> int:
    return client.post(f"/api/studies/{study_id}/participants", headers=ADMIN).json()["id"]


def _other_studys_participant(client: TestClient) -> int:
    return finished_participant(client, new_study(client, seed=4)["id"])


def test_the_launch_form_pools_all_or_the_ticked_participants(
    client: TestClient, study: dict, people: list[int]
) -> None:
    page = logged_in(client)
    html = page.get(f"/runs/new?study_id={study['id']}").text
    assert 'value="pool:all"' in html and 'value="pool:chosen"' in html
    assert all(f'name="pool_{pid}"' in html for pid in people) and audit(html) == []
    fields = {
        "csrf_token": csrf_token(page, f"/runs/new?study_id={study['id']}"),
        "study_id": str(study["id"]),
        "algo": "ppo",
        "timesteps": "128",
        "seed": "0",
        "n_envs": "1",
        "num_steps": "128",
    }
    one = page.post("/runs", data=fields | {"advice": "pool:chosen", f"pool_{people[0]}": "on"})
    assert one.status_code == 422 and "at least two participants, got 1" in one.text
    assert re.search(rf'name="pool_{people[0]}" value="on"\s+checked', one.text)
    chosen = {f"pool_{pid}": "on" for pid in people[:2]}
    for advice, extra, ids in (("pool:all", {}, people), ("pool:chosen", chosen, people[:2])):
        response = page.post("/runs", data=fields | {"advice": advice, **extra})
        assert response.status_code == 303, response.text
        run = wait_run(client, int(response.headers["location"].rsplit("/", 1)[1]))
        assert run["participant_ids"] == sorted(ids) and run["status"] == "succeeded"
