"""Reliability-weighted pooled advice and excluded participants (issue 28 §1, §2) through
``/api/runs``, the new-run form, the run page and the label exports: a weighted run records
each participant's weight and why the pool weighted them down, trains and judges with those
weights; an excluded participant is left out of pools and exports, and their labels are kept.
On PostgreSQL only (``postgres_only``: training, not storage, is the subject).
"""

from __future__ import annotations

import csv
import io
import json
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pyarrow.parquet as pq
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db import make_engine, make_sessions
from app.labelling import check
from app.labelling.participant_quality import ParticipantQuality
from app.models import Label, Match, Participant
from app.runs import service as runs
from app.settings import Settings
from app.studies.downloads import tree_filename
from engine.pooling import pooled_tree
from engine.rl.runner import load_run_advice, load_run_config
from engine.treefile import tree_from_json, tree_to_json
from tests.support.crowd import configure
from tests.support.runs import TINY, create_run, finished_participant, run_app, wait_run
from tests.support.studies import Player, new_study
from tests.support.web import ADMIN, audit, csrf_token, logged_in

pytestmark = [pytest.mark.training, pytest.mark.postgres_only]


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    return new_study(client)


@pytest.fixture(scope="module")
def people(client: TestClient, settings: Settings, study: dict[str, Any]) -> list[int]:
    """Three finished participants whose trees differ: the first passes the consistency
    check, the second fails it, the third answers none."""
    first = finished_participant(client, study["id"])
    body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    Player(client, body["id"], body["token"], body["invite_url"]).play(
        lambda m: m["b"]["candidate_id"]
    )
    third = finished_participant(client, study["id"])
    configure(client, study["id"], consistency_check=True)
    _answer_check(settings, first, agree=True)
    _answer_check(settings, body["id"], agree=False)
    return [first, body["id"], third]


@contextmanager
def _session(settings: Settings) -> Iterator[Session]:
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            yield session
    finally:
        engine.dispose()


def _answer_check(settings: Settings, participant_id: int, *, agree: bool) -> None:
    """Answer the participant's consistency check (the services: the check has pages only)
    as their label of the pair, or the other way."""
    with _session(settings) as session:
        person = session.get_one(Participant, participant_id)
        pair = check.pending_pair(session, participant=person)
        assert pair is not None
        match = session.get_one(Match, pair.match_id)
        label = session.scalar(select(Label.winner).where(Label.match_id == match.id))
        assert label is not None
        other = match.b if label == match.a else match.a
        check.answer(session, participant=person, winner=label if agree else other)


def _exclude(settings: Settings, participant_id: int, reason: str | None) -> None:
    with _session(settings) as session:
        person = session.get_one(Participant, participant_id)
        person.excluded, person.exclusion_reason = True, reason
        session.commit()


def api(client: TestClient, path: str, status: int = 200) -> Any:
    response = client.get(path, headers=ADMIN)
    assert response.status_code == status, response.text
    return response.json()


def _reliability(client: TestClient, study_id: int) -> dict[int, float]:
    quality = api(client, f"/api/studies/{study_id}/quality")
    return {p["participant_id"]: p["reliability"] for p in quality["participants"]}


def test_a_weighted_run_records_its_weights_and_trains_with_them(
    client: TestClient, settings: Settings, study: dict[str, Any], people: list[int]
) -> None:
    run_id = create_run(
        client,
        study_id=study["id"],
        participant_ids=people,
        pool_weighting="reliability",
        algo="bipars-em",
        timesteps=128,
        **TINY,
    )
    run = wait_run(client, run_id)
    assert run["status"] == "succeeded", run
    reliability = _reliability(client, study["id"])
    weights = [reliability[p] for p in people]
    assert run["pool_weighting"] == "reliability" and run["config"]["pool_weights"] == weights
    assert run["advice"].startswith("3 participants pooled by reliability (")
    # the first passed its check (the highest weight), the others are weighted down
    assert weights[0] > weights[2] > weights[1] > 0
    got = {w["participant_id"]: (w["weight"], w["why"]) for w in run["pool_weights"]}
    assert got[people[0]] == (weights[0], None)
    assert got[people[1]] == (
        weights[1],
        f"reliability {weights[1]:.2f} from 1 known-answer check: failed the consistency check",
    )
    assert got[people[2]][1].startswith(f"reliability {weights[2]:.2f}: no known-answer check")
    # the verdict is engine pooling with those weights, and so is what the run trained on
    trees = [tree_from_json(api(client, f"/api/participants/{p}/tree")) for p in people]
    verdict = api(client, f"/api/runs/{run_id}/advice-tree")
    weighted = pooled_tree(trees, weights=weights)
    assert verdict == tree_to_json(weighted) and weighted.scores != pooled_tree(trees).scores
    run_dir = settings.data_dir / "runs" / str(run_id)
    assert load_run_config(run_dir).pool_weights == tuple(weights)
    trained_on = load_run_advice(run_dir)
    assert trained_on is not None and tree_to_json(trained_on) == verdict
    page = logged_in(client).get(f"/runs/{run_id}").text
    assert 'id="pool-weights"' in page and "failed the consistency check" in page
    assert audit(page) == []


def test_the_plain_mean_stays_the_default_and_is_other_advice(
    client: TestClient, settings: Settings, study: dict[str, Any], people: list[int]
) -> None:
    """A pool without ``pool_weighting`` is the plain mean, as before; the multi-run
    comparison keeps it apart from the same pool weighted by reliability."""
    body = {"study_id": study["id"], "participant_ids": people, "algo": "ppo"}
    # its own weighted run: under xdist another worker may have run the test that makes one
    weighted = [create_run(client, **body, pool_weighting="reliability", timesteps=128, **TINY)]
    run = wait_run(client, create_run(client, **body, timesteps=128, **TINY))
    assert run["pool_weighting"] == "mean" and run["pool_weights"] is None
    assert "pool_weights" not in run["config"] and run["status"] == "succeeded"
    assert run["advice"].startswith("3 participants pooled (")
    with _session(settings) as session:
        same = [
            r.id
            for r in runs.same_advice_runs(session, run=runs.get_run(session, run_id=run["id"]))
        ]
    assert run["id"] in same and weighted and not set(weighted) & set(same)
    one = {"study_id": study["id"], "participant_id": people[0], "algo": "ppo"}
    run = wait_run(client, create_run(client, **one, timesteps=128, **TINY))
    assert run["pool_weighting"] is None and run["pool_weights"] is None


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"pool_weighting": "foo"}, "pool_weighting"),
        ({"pool_weighting": True}, "pool_weighting"),
        ({"pool_weighting": None}, "pool_weighting"),
        ({"pool_weighting": "reliability", "participant_ids": None, "teacher": "standing"}, "pool"),
    ],
    ids=["unknown", "json-true", "null", "no-pool"],
)
def test_bad_weighting_is_422_and_creates_nothing(
    client: TestClient, study: dict[str, Any], people: list[int], change: dict, words: str
) -> None:
    before = api(client, f"/api/runs?study_id={study['id']}")
    body = {"study_id": study["id"], "participant_ids": people, "algo": "ppo", "timesteps": 128}
    response = client.post("/api/runs", json=body | change, headers=ADMIN)
    assert response.status_code == 422, response.text
    assert words in str(response.json()["detail"])
    assert api(client, f"/api/runs?study_id={study['id']}") == before


def test_a_pool_whose_reliabilities_are_all_zero_is_refused(
    client: TestClient, study: dict[str, Any], people: list[int], monkeypatch
) -> None:
    monkeypatch.setattr(ParticipantQuality, "reliability", property(lambda self: 0.0))
    before = api(client, f"/api/runs?study_id={study['id']}")
    body = {"study_id": study["id"], "participant_ids": people, "algo": "ppo", "timesteps": 128}
    response = client.post(
        "/api/runs", json=body | {"pool_weighting": "reliability"}, headers=ADMIN
    )
    assert response.status_code == 409, response.text
    assert response.json()["detail"].startswith(
        "every pooled participant has reliability 0; use the plain mean"
    )
    assert api(client, f"/api/runs?study_id={study['id']}") == before


def test_the_form_launches_a_weighted_pool(
    client: TestClient, study: dict[str, Any], people: list[int]
) -> None:
    page = logged_in(client)
    html = page.get(f"/runs/new?study_id={study['id']}").text
    assert 'id="pool_weighting"' in html and 'value="reliability"' in html
    fields = {
        "csrf_token": csrf_token(page, f"/runs/new?study_id={study['id']}"),
        "study_id": str(study["id"]),
        "advice": "pool:chosen",
        "algo": "ppo",
        "timesteps": "128",
        "seed": "0",
        "n_envs": "1",
        "num_steps": "128",
        **{f"pool_{pid}": "on" for pid in people},
    }
    bad = page.post("/runs", data=fields | {"pool_weighting": "foo"})
    assert bad.status_code == 422 and 'id="pool_weighting-error"' in bad.text
    response = page.post("/runs", data=fields | {"pool_weighting": "reliability"})
    assert response.status_code == 303, response.text
    run = wait_run(client, int(response.headers["location"].rsplit("/", 1)[1]))
    assert run["pool_weighting"] == "reliability" and run["participant_ids"] == people
    assert run["status"] == "succeeded"


def test_an_excluded_participant_is_left_out_of_pools_and_exports(
    client: TestClient, settings: Settings, study: dict[str, Any], people: list[int]
) -> None:
    """Runs last in this module: it adds and excludes a fourth participant."""
    gone = finished_participant(client, study["id"])
    _exclude(settings, gone, "failed the gold gate")
    every = {"study_id": study["id"], "all_participants": True, "algo": "ppo", "timesteps": 128}
    run = wait_run(client, create_run(client, **every, **TINY))
    assert run["participant_ids"] == people and run["status"] == "succeeded"
    body = every | {"all_participants": False, "participant_ids": [people[0], gone]}
    response = client.post("/api/runs", json=body, headers=ADMIN)
    assert response.status_code == 409
    assert response.json()["detail"] == (
        f"participant {gone} is excluded from pooling (failed the gold gate); leave them out"
    )
    form = logged_in(client).get(f"/runs/new?study_id={study['id']}").text
    assert f'name="pool_{gone}"' not in form and f'name="pool_{people[0]}"' in form
    _check_exports(client, study["id"], people, gone)


def _check_exports(client: TestClient, study_id: int, people: list[int], gone: int) -> None:
    """The exports leave ``gone`` out unless asked, and keep their labels."""
    base = f"/api/studies/{study_id}/export/labels"
    rows = _jsonl(client, base + ".jsonl")
    assert {r["participant_id"] for r in rows} == set(people)
    everyone = _jsonl(client, base + ".jsonl?include_excluded=true")
    assert {r["participant_id"] for r in everyone} == {*people, gone}
    reliability = _reliability(client, study_id)
    for r in everyone:
        assert r["excluded"] is (r["participant_id"] == gone) and r["tie"] is False
        assert r["reliability"] == reliability[r["participant_id"]]
    csv_url = f"/api/studies/{study_id}/labels.csv"
    plain = csv.DictReader(io.StringIO(client.get(csv_url, headers=ADMIN).text))
    assert all(r["participant_id"] != str(gone) for r in plain)  # left out by default
    asked = client.get(csv_url + "?include_excluded=true", headers=ADMIN).text
    kept = [r for r in csv.DictReader(io.StringIO(asked)) if r["participant_id"] == str(gone)]
    assert len([r for r in everyone if r["participant_id"] == gone]) == len(kept) > 0
    table = list(csv.DictReader(io.StringIO(client.get(base + ".csv", headers=ADMIN).text)))
    assert list(table[0])[-8:] == [
        "tie",
        "stimulus",
        "reliability",
        "gold_right",
        "gold_asked",
        "excluded",
        "outcome",
        "code",
    ] and len(table) == len(rows)
    assert {r["excluded"] for r in table} == {"False"}
    parquet = pq.read_table(
        io.BytesIO(client.get(base + ".parquet?include_excluded=1", headers=ADMIN).content)
    )
    assert parquet.column("excluded").to_pylist() == [r["excluded"] for r in everyone]
    assert parquet.column("reliability").to_pylist() == [r["reliability"] for r in everyone]
    bad = client.get(base + ".jsonl?include_excluded=maybe", headers=ADMIN)
    assert bad.status_code == 422 and "include_excluded" in str(bad.json()["detail"])
    _check_trees(client, study_id, people, gone)


def _check_trees(client: TestClient, study_id: int, people: list[int], gone: int) -> None:
    """The trees API and zip leave ``gone`` out unless asked; the study page draws and flags
    them."""
    url = f"/api/studies/{study_id}/trees"
    listed = [t["participant_id"] for t in client.get(url, headers=ADMIN).json()]
    asked = client.get(url + "?include_excluded=true", headers=ADMIN).json()
    assert listed == people and [t["participant_id"] for t in asked] == sorted([*people, gone])
    page = logged_in(client)
    for query, expected in (("", people), ("?include_excluded=true", sorted([*people, gone]))):
        archive = zipfile.ZipFile(
            io.BytesIO(page.get(f"/studies/{study_id}/trees.zip{query}").content)
        )
        assert sorted(archive.namelist()) == sorted(tree_filename(study_id, p) for p in expected)
    html = page.get(f"/studies/{study_id}").text
    assert "trees?include_excluded=true" in html
    heading = html.split(f"Participant #{gone}", 1)[1].split("</h3>", 1)[0]
    assert '<span class="flag">excluded</span>' in heading


def _jsonl(client: TestClient, path: str) -> list[dict[str, Any]]:
    response = client.get(path, headers=ADMIN)
    assert response.status_code == 200, response.text
    return [json.loads(line) for line in response.text.splitlines()]
