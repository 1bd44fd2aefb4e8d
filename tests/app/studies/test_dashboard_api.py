"""The researcher's live dashboard through the REST API (issue 29 §1), on SQLite and
PostgreSQL: its counts move as participants join, label, finish and decline; each
participant's progress, median time, flags and gold accuracy agree with ``/quality``; an
unchanged dashboard answers 304 to its ETag; unknown studies are 404 and strangers 401."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.crowd import configure, visit, visitor
from tests.support.studies import Player
from tests.support.web import ADMIN


def board(client: TestClient, study_id: int, **headers: str) -> dict[str, Any]:
    response = client.get(f"/api/studies/{study_id}/dashboard", headers=ADMIN | headers)
    assert response.status_code == 200, response.text
    assert response.headers["etag"] == response.json()["version"]
    return response.json()


def counts(client: TestClient, study_id: int) -> tuple[int, ...]:
    """(joined, not started, labelling, finished, declined) now."""
    c = board(client, study_id)["counts"]
    return c["joined"], c["not_started"], c["labelling"], c["finished"], c["declined"]


def decline(client: TestClient, link: dict[str, Any]) -> None:
    browser, page = visit(client, link, "?PROLIFIC_PID=no-thanks")
    csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
    answer = browser.post(
        f"/s/{link['slug']}",
        data={"csrf_token": csrf, "decision": "decline", "PROLIFIC_PID": "no-thanks"},
    )
    assert answer.status_code == 200 and "You declined" in answer.text


def label_once(player: Player, **extra: Any) -> None:
    match = player.next_match()
    assert match is not None
    assert player.label(match["match_id"], match["a"]["candidate_id"], **extra).status_code == 201


def test_counts_move_as_people_join_label_finish_and_decline(client, make_study, invite) -> None:
    study = make_study(n_candidates=4, seed=21)
    sid = study["id"]
    link = configure(client, sid, consent_text="We store your choices.")
    empty = board(client, sid)
    assert empty["counts"] == {
        "joined": 0,
        "not_started": 0,
        "labelling": 0,
        "finished": 0,
        "declined": 0,
        "excluded": 0,
        "withdrawn": 0,
        "timed_out": 0,
    }
    assert (empty["participants"], empty["labels"], empty["max_participants"]) == ([], 0, 50)
    first = invite(sid)
    assert counts(client, sid) == (1, 1, 0, 0, 0)
    label_once(first)
    assert counts(client, sid) == (1, 0, 1, 0, 0)
    now = board(client, sid)
    assert (now["labels"], now["labels_last_minute"]) == (1, 1)
    assert now["labels_per_minute"] == pytest.approx(0.2)
    first.play()
    assert counts(client, sid) == (1, 0, 0, 1, 0)
    decline(client, link)
    assert counts(client, sid) == (1, 0, 0, 1, 1)
    browser, answer = visit(client, link, "?PROLIFIC_PID=yes-please")
    browser.post(
        f"/s/{link['slug']}",
        data={
            "csrf_token": answer.text.split('name="csrf_token" value="')[1].split('"')[0],
            "decision": "agree",
            "PROLIFIC_PID": "yes-please",
        },
    )
    assert counts(client, sid) == (2, 1, 0, 1, 1)
    rows = board(client, sid)["participants"]
    assert [(r["participant_id"], r["status"], r["done"], r["total"]) for r in rows] == [
        (first.id, "finished", 3, 3),
        (rows[1]["participant_id"], "not_started", 0, 3),
    ]
    assert rows[1]["external_id"] == "yes-please"


def test_unchanged_is_304_and_any_change_a_new_etag(client, study, invite) -> None:
    sid = study["id"]
    player = invite()
    etag = board(client, sid)["version"]
    url = f"/api/studies/{sid}/dashboard"
    for sent in (etag, f"W/{etag}", f'"other", {etag}', "*"):
        same = client.get(url, headers=ADMIN | {"If-None-Match": sent})
        assert (same.status_code, same.content, same.headers["etag"]) == (304, b"", etag)
    label_once(player)
    after_label = client.get(url, headers=ADMIN | {"If-None-Match": etag})
    assert after_label.status_code == 200 and after_label.headers["etag"] != etag
    etag = after_label.headers["etag"]
    excluded = client.put(
        f"/api/participants/{player.id}/exclusion", json={"excluded": True}, headers=ADMIN
    )
    assert excluded.status_code == 200
    after_exclusion = client.get(url, headers=ADMIN | {"If-None-Match": etag})
    assert after_exclusion.status_code == 200
    mine = next(
        p for p in after_exclusion.json()["participants"] if p["participant_id"] == player.id
    )
    assert mine["excluded"] is True and after_exclusion.json()["counts"]["excluded"] >= 1
    etag = after_exclusion.headers["etag"]
    assert (
        player.client.post("/api/participants/me/undo", headers=player.headers).status_code == 200
    )
    assert client.get(url, headers=ADMIN | {"If-None-Match": etag}).status_code == 200


def test_median_flags_and_gold_agree_with_quality(client, make_study, invite) -> None:
    study = make_study(n_candidates=5, seed=4)  # 4 matches: an even count of times
    sid = study["id"]
    item = client.post(
        f"/api/studies/{sid}/gold",
        json={"kind": "pair", "a": 0, "b": 1, "answer": 1},
        headers=ADMIN,
    )
    assert item.status_code == 201, item.text
    configure(client, sid, speed_threshold_ms=500, gold_gate=0.99)  # 0 of 1: bound 0.975
    fast, slow = invite(sid), invite(sid)
    for player, times in ((fast, [100, 400, 200, 900]), (slow, [2000, 3000, 1000, 5000])):
        pending = iter(times)
        while (match := player.next_match()) is not None:
            if match["gold"]:  # the fast one answers wrong, the slow one right
                winner = 0 if player is fast else 1
                assert player.answer_gold(match["gold"]["item_id"], winner).status_code == 201
                continue
            sent = player.label(match["match_id"], match["left"], response_ms=next(pending))
            assert sent.status_code == 201, sent.text
    rows = {r["participant_id"]: r for r in board(client, sid)["participants"]}
    assert rows[fast.id]["median_response_ms"] == pytest.approx(300.0)
    assert rows[slow.id]["median_response_ms"] == pytest.approx(2500.0)
    quality = client.get(f"/api/studies/{sid}/quality", headers=ADMIN).json()["participants"]
    for q in quality:
        live = rows[q["participant_id"]]
        assert live["median_response_ms"] == pytest.approx(q["median_response_ms"])
        assert live["flags"] == q["flags"]
        assert (live["gold_right"], live["gold_asked"]) == (q["gold_right"], q["gold_asked"])
    assert "fast" in rows[fast.id]["flags"] and "below_gate" in rows[fast.id]["flags"]
    assert (rows[slow.id]["gold_right"], rows[slow.id]["gold_asked"]) == (1, 1)


def test_unknown_study_is_404_and_strangers_401(client, study, invite) -> None:
    missing = client.get("/api/studies/999999/dashboard", headers=ADMIN)
    assert missing.status_code == 404 and "not found" in missing.json()["detail"]
    assert visitor(client).get(f"/api/studies/{study['id']}/dashboard").status_code == 401
    person = invite()
    as_participant = client.get(f"/api/studies/{study['id']}/dashboard", headers=person.headers)
    assert as_participant.status_code == 401
    assert client.get("/api/studies/0/dashboard", headers=ADMIN).status_code == 422


def test_an_overlong_if_none_match_is_422(client, study) -> None:
    response = client.get(
        f"/api/studies/{study['id']}/dashboard", headers=ADMIN | {"If-None-Match": "x" * 3000}
    )
    assert response.status_code == 422 and "detail" in response.json()
