"""Limits and reuse that hold under concurrency (issue 45 §4), on SQLite and PostgreSQL.

14 webhooks or 14 gold items posted at once against a limit of 10 store exactly 10 (the
owner's counter, moved by ``UPDATE ... WHERE n < 10``), and removing one frees exactly one
place; two identical experiments posted at once share their baseline and pilot runs (the
partial unique index on runs). Every request waits at a barrier, then all go; the tests
assert the invariant (the count is the limit, the runs are the planned ones), never who won.
No run trains (the run worker is off).
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select, update

from app.db import writing
from app.models import GoldItem, Run, RunStatus, Study, Survey, Webhook
from app.studies.gold import MAX_GOLD_ITEMS
from app.webhooks.service import MAX_WEBHOOKS
from tests.support.runs import TINY, run_app
from tests.support.studies import new_study
from tests.support.surveys import paper_body, participant_trees
from tests.support.web import ADMIN

AT_ONCE = 14
EXPERIMENT = {"teacher": "good", "algo": "bipars-em", "timesteps": 512, "seeds": 2, **TINY}


@pytest.fixture(scope="module")
def client(settings) -> Iterator[TestClient]:
    with run_app(settings, worker=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def study(client: TestClient) -> dict[str, Any]:
    ready = new_study(client, n_candidates=4, seed=45)
    assert ready["status"] == "ready", ready
    return ready


def at_once(n: int, call: Callable[[int], httpx.Response]) -> list[httpx.Response]:
    """``call(0) .. call(n - 1)`` on ``n`` threads, released together by a barrier."""
    start = threading.Barrier(n)

    def go(i: int) -> httpx.Response:
        start.wait(timeout=60)
        return call(i)

    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(go, range(n)))


def _scalar(client: TestClient, query: Any) -> Any:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(query)


def _hook(client: TestClient, i: int, **owner: int) -> httpx.Response:
    body = {"url": f"http://127.0.0.1:9/hook-{i}", **owner}
    return client.post("/api/webhooks", json=body, headers=ADMIN)


def test_webhooks_posted_at_once_stop_at_the_limit(client, study) -> None:
    owner = {"study_id": study["id"]}
    answers = at_once(AT_ONCE, lambda i: _hook(client, i, **owner))
    assert Counter(r.status_code for r in answers) == {201: MAX_WEBHOOKS, 409: 4}
    refused = {r.json()["detail"] for r in answers if r.status_code == 409}
    assert refused == {f"a study has at most {MAX_WEBHOOKS} webhooks"}
    listed = client.get(f"/api/webhooks?study_id={study['id']}", headers=ADMIN).json()
    assert len(listed) == MAX_WEBHOOKS
    count = select(Study.webhook_count).where(Study.id == study["id"])
    assert _scalar(client, count) == MAX_WEBHOOKS
    # Removing one, twice at once, frees one place: one 204, one 404.
    gone = at_once(2, lambda _: client.delete(f"/api/webhooks/{listed[0]['id']}", headers=ADMIN))
    assert sorted(r.status_code for r in gone) == [204, 404]
    assert _scalar(client, count) == MAX_WEBHOOKS - 1
    again = at_once(3, lambda i: _hook(client, 100 + i, **owner))
    assert sorted(r.status_code for r in again) == [201, 409, 409]
    stored = select(func.count()).where(Webhook.study_id == study["id"])
    assert _scalar(client, stored) == _scalar(client, count) == MAX_WEBHOOKS


def test_a_survey_has_its_own_webhook_limit(client, study) -> None:
    trees = participant_trees(client, study["id"])
    survey = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN).json()
    answers = at_once(AT_ONCE, lambda i: _hook(client, i, survey_id=survey["id"]))
    assert Counter(r.status_code for r in answers) == {201: MAX_WEBHOOKS, 409: 4}
    refused = {r.json()["detail"] for r in answers if r.status_code == 409}
    assert refused == {f"a survey has at most {MAX_WEBHOOKS} webhooks"}
    count = select(Survey.webhook_count).where(Survey.id == survey["id"])
    stored = select(func.count()).where(Webhook.survey_id == survey["id"])
    assert _scalar(client, stored) == _scalar(client, count) == MAX_WEBHOOKS


def _gold(client: TestClient, study_id: int) -> httpx.Response:
    body = {"kind": "pair", "a": 0, "b": 1, "answer": 0}
    return client.post(f"/api/studies/{study_id}/gold", json=body, headers=ADMIN)


def test_gold_items_posted_at_once_stop_at_the_limit(client, study) -> None:
    sid = study["id"]
    answers = at_once(AT_ONCE, lambda _: _gold(client, sid))
    assert Counter(r.status_code for r in answers) == {201: MAX_GOLD_ITEMS, 422: 4}
    refused = {r.json()["detail"] for r in answers if r.status_code == 422}
    assert refused == {f"a study has at most {MAX_GOLD_ITEMS} gold items"}
    items = client.get(f"/api/studies/{sid}/gold", headers=ADMIN).json()
    assert len(items) == MAX_GOLD_ITEMS
    count = select(Study.gold_item_count).where(Study.id == sid)
    assert _scalar(client, count) == MAX_GOLD_ITEMS
    first = f"/api/studies/{sid}/gold/{items[0]['id']}"
    gone = at_once(2, lambda _: client.delete(first, headers=ADMIN))
    assert sorted(r.status_code for r in gone) == [204, 404]
    assert _scalar(client, count) == MAX_GOLD_ITEMS - 1
    again = at_once(3, lambda _: _gold(client, sid))
    assert sorted(r.status_code for r in again) == [201, 422, 422]
    stored = select(func.count()).where(GoldItem.study_id == sid)
    assert _scalar(client, stored) == _scalar(client, count) == MAX_GOLD_ITEMS


def _shared(experiment: dict[str, Any]) -> list[int]:
    return [r["id"] for r in experiment["runs"] if r["role"] != "advised"]


def _runs_per_algo(client: TestClient, study_id: int, timesteps: int) -> Counter[str]:
    with client.app.state.runtime.sessions() as session:
        found = session.scalars(
            select(Run.algo).where(Run.study_id == study_id, Run.timesteps == timesteps)
        )
        return Counter(str(algo) for algo in found)


@pytest.mark.parametrize("timesteps", [512, 768, 1024])  # each its own baseline
def test_two_identical_experiments_at_once_share_one_baseline(client, study, timesteps) -> None:
    body = {"study_id": study["id"], **EXPERIMENT, "pilot_seeds": 1, "timesteps": timesteps}
    answers = at_once(2, lambda _: client.post("/api/experiments", json=body, headers=ADMIN))
    assert [r.status_code for r in answers] == [202, 202], [r.text for r in answers]
    first, second = (r.json() for r in answers)
    assert first["id"] != second["id"]
    assert _shared(first) == _shared(second) and len(_shared(first)) == 3
    advised = [r["id"] for e in (first, second) for r in e["runs"] if r["role"] == "advised"]
    assert len(set(advised)) == 4  # each its own advised runs
    assert _runs_per_algo(client, study["id"], timesteps) == {"ppo": 3, "bipars-em": 4}


def test_a_failed_baseline_gives_its_place_and_a_plain_run_trains_anew(client, study) -> None:
    body = {"study_id": study["id"], **EXPERIMENT, "pilot_seeds": 1, "timesteps": 1280}
    created = client.post("/api/experiments", json=body, headers=ADMIN).json()
    baseline = next(r for r in created["runs"] if r["role"] == "baseline")
    plain = {k: v for k, v in body.items() if k not in ("seeds", "pilot_seeds")}
    again = client.post(
        "/api/runs", json=plain | {"algo": "ppo", "seed": baseline["seed"]}, headers=ADMIN
    )
    assert again.status_code == 202, again.text
    assert again.json()["id"] != baseline["id"]  # POST /api/runs always trains its own run
    with client.app.state.runtime.sessions() as session, writing(session):
        failed = update(Run).where(Run.id == baseline["id"]).values(status=RunStatus.FAILED)
        session.execute(failed)
    after = client.post("/api/experiments", json=body, headers=ADMIN).json()
    seed = baseline["seed"]
    replaced = [r["id"] for r in after["runs"] if r["role"] == "baseline" and r["seed"] == seed]
    assert replaced and replaced[0] != baseline["id"]
    # the other baseline and the pilot are still the shared ones
    assert set(_shared(after)) - set(replaced) == set(_shared(created)) - {baseline["id"]}
