"""Disagreement pairs (issue 25 §5): after the bracket, pairs where the participant's advice
and a no-advice baseline disagree; refused (422) until such a baseline has finished on the
env; answered through the API and the pages, exported with the labels, counted by the
study's power estimate, never part of the tree. SQLite and PostgreSQL."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.settings import Settings
from engine.disagreement import disagreement_pairs
from engine.treefile import tree_from_json
from engine.verdict import advice_scores
from tests.support.runs import TINY, create_run, run_app, wait_run
from tests.support.studies import Player, new_study, wait_ready
from tests.support.web import ADMIN, browser, csrf_token, logged_in

pytestmark = pytest.mark.training

K = 4
BODY: dict[str, Any] = {
    "name": "pairs",
    "env_id": "Hopper-v5",
    "n_candidates": 8,
    "p": 0.9,
    "seed": 11,
    "disagreement_pairs": K,
}
NO_BASELINE = "disagreement pairs need a finished no-advice ppo run on Hopper-v5; train one first"


@pytest.fixture(scope="module")
def client(settings: Settings) -> Iterator[TestClient]:
    with run_app(settings) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def baseline(client: TestClient) -> int:
    """A finished tiny no-advice ppo run on Hopper (of another study)."""
    host = new_study(client)
    run = create_run(client, study_id=host["id"], algo="ppo", timesteps=256, **TINY)
    assert wait_run(client, run)["status"] == "succeeded"
    return run


@pytest.fixture(scope="module")
def study(client: TestClient, baseline: int) -> dict[str, Any]:
    created = client.post("/api/studies", json=BODY, headers=ADMIN)
    assert created.status_code == 201, created.text
    ready = wait_ready(client, created.json()["id"], timeout_s=120)
    assert ready["status"] == "ready" and ready["disagreement_pairs"] == K, ready
    return ready


@pytest.fixture(scope="module")
def returns(client: TestClient, study: dict[str, Any]) -> np.ndarray:
    """The baseline's return from each candidate, as stored."""
    got = client.get(f"/api/studies/{study['id']}/candidates", headers=ADMIN).json()
    return np.array([c["baseline_return"] for c in sorted(got, key=lambda c: c["id"])])


def _invite(client: TestClient, study: dict[str, Any]) -> Player:
    body = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    return Player(client, body["id"], body["token"], body["invite_url"])


def _against(returns: np.ndarray):
    """A participant who always picks the state the baseline does worse from."""
    return lambda match: min((match["a"], match["b"]), key=lambda s: returns[s["candidate_id"]])[
        "candidate_id"
    ]


def _pairs(player: Player) -> list[dict[str, Any]]:
    response = player.client.get("/api/participants/me/pairs", headers=player.headers)
    assert response.status_code == 200, response.text
    return response.json()


def _answer(player: Player, position: int, winner: Any, **extra: Any):
    return player.client.post(
        f"/api/participants/me/pairs/{position}/label",
        headers=player.headers,
        json={"winner": winner, **extra},
    )


def test_refused_until_a_no_advice_baseline_has_finished(client: TestClient) -> None:
    """Runs first in this module: its database has no run yet."""
    refused = client.post("/api/studies", json=BODY, headers=ADMIN)
    assert refused.status_code == 422 and refused.json() == {"detail": NO_BASELINE}
    for bad in (-1, 11, True, 2.5, "3"):
        answer = client.post("/api/studies", json=BODY | {"disagreement_pairs": bad}, headers=ADMIN)
        assert answer.status_code == 422 and "disagreement_pairs" in answer.text, bad


def test_the_form_says_why_and_keeps_the_input(client: TestClient) -> None:
    """Before any baseline (this module's second test): the form refuses, with the reason."""
    page = logged_in(client)
    fields = {k: str(v) for k, v in BODY.items()} | {"sampling": "uniform", "instructions": ""}
    for pairs, reason in (("2", NO_BASELINE), ("11", "less than or equal to 10")):
        token = csrf_token(page, "/studies/new")
        refused = page.post(
            "/studies", data=fields | {"disagreement_pairs": pairs, "csrf_token": token}
        )
        assert refused.status_code == 422 and reason in refused.text, pairs
        assert 'name="disagreement_pairs" type="number" min="0"' in refused.text
        assert f'max="10" value="{pairs}"' in refused.text  # the input kept


def test_candidates_carry_the_baseline_return(returns: np.ndarray) -> None:
    assert returns.shape == (8,) and np.isfinite(returns).all()
    assert np.ptp(returns) > 0  # the baseline prefers some states: pairs can disagree


def test_pairs_come_after_the_bracket_and_never_enter_the_tree(
    client: TestClient, study: dict[str, Any], returns: np.ndarray
) -> None:
    player = _invite(client, study)
    assert _pairs(player) == []  # bracket unfinished
    assert _answer(player, 0, 0).status_code == 404
    player.play(_against(returns))
    tree_url = f"/api/participants/{player.id}/tree"
    tree = client.get(tree_url, headers=ADMIN).json()
    pairs = _pairs(player)
    doc = tree_from_json(tree)
    played = [(m.a, m.b) for m, _ in doc.matches]
    expected = disagreement_pairs(advice_scores(doc), returns, k=K, played=played)
    assert 0 < len(pairs) == len(expected) <= K
    assert [{p["left"], p["right"]} for p in pairs] == [set(e) for e in expected]
    assert all(p["total"] == len(pairs) and p["winner"] is None for p in pairs)
    assert _pairs(player) == pairs  # chosen once

    first = pairs[0]
    assert _answer(player, 0, first["left"], response_ms=1500).status_code == 201
    assert _answer(player, 0, first["left"]).status_code == 200  # the same again
    conflict = _answer(player, 0, first["right"])
    assert conflict.status_code == 409 and "already answered" in conflict.json()["detail"]
    last = pairs[-1]
    stranger = next(c for c in range(8) if c not in (last["left"], last["right"]))
    assert _answer(player, last["position"], stranger).status_code == 422
    assert _answer(player, K + 1, first["left"]).status_code == 404
    assert _answer(player, 11, first["left"]).status_code == 422  # beyond any study's pairs
    assert _answer(player, 0, False).status_code == 422  # a JSON false is not an id
    assert _pairs(player)[0]["winner"] == first["left"]
    assert client.get(tree_url, headers=ADMIN).json() == tree


def test_undoing_the_final_label_chooses_the_pairs_again(
    client: TestClient, study: dict[str, Any], returns: np.ndarray
) -> None:
    player = _invite(client, study)
    player.play(_against(returns))
    assert len(_pairs(player)) > 0
    undone = client.post("/api/participants/me/undo", headers=player.headers)
    assert undone.status_code == 200, undone.text
    assert _pairs(player) == []  # unfinished again: nothing is asked
    final = player.next_match()
    assert final is not None
    keeps = _against(returns)(final)
    other = final["a"]["candidate_id"] + final["b"]["candidate_id"] - keeps
    assert player.label(final["match_id"], other).status_code == 201  # the other way now
    doc = tree_from_json(client.get(f"/api/participants/{player.id}/tree", headers=ADMIN).json())
    played = [(m.a, m.b) for m, _ in doc.matches]
    expected = disagreement_pairs(advice_scores(doc), returns, k=K, played=played)
    assert [{p["left"], p["right"]} for p in _pairs(player)] == [set(e) for e in expected]


def test_answers_are_exported_and_counted_by_the_power_estimate(
    client: TestClient, study: dict[str, Any], returns: np.ndarray
) -> None:
    player = _invite(client, study)
    player.play(_against(returns))
    before = _power_of(client, study, player)
    pairs = _pairs(player)
    for p in pairs:
        assert _answer(player, p["position"], p["left"]).status_code == 201
    rows = [
        json.loads(line)
        for line in client.get(
            f"/api/studies/{study['id']}/export/labels.jsonl", headers=ADMIN
        ).text.splitlines()
    ]
    mine = [r for r in rows if r["participant_id"] == player.id]
    assert [r["kind"] for r in mine] == ["bracket"] * 7 + ["disagreement"] * len(pairs)
    assert [(r["left"], r["right"], r["winner"], r["side"]) for r in mine[7:]] == [
        (p["left"], p["right"], p["left"], "left") for p in pairs
    ]
    assert all(r["match_id"] is None and r["round"] is None for r in mine[7:])
    csv = client.get(f"/api/studies/{study['id']}/export/labels.csv", headers=ADMIN).text
    assert csv.splitlines()[0].split(",")[4] == "kind" and ",disagreement," in csv
    after = _power_of(client, study, player)
    assert after["n_matches"] == before["n_matches"] + len(pairs) == 7 + len(pairs)


def _power_of(client: TestClient, study: dict[str, Any], player: Player) -> dict[str, Any]:
    rows = client.get(f"/api/studies/{study['id']}/power", headers=ADMIN).json()
    return next(r for r in rows if r["participant_id"] == player.id)


def test_the_pages_ask_the_pairs_before_thanking(
    client: TestClient, study: dict[str, Any], returns: np.ndarray
) -> None:
    player = _invite(client, study)
    player.play(_against(returns))
    total = len(_pairs(player))
    page = browser(client)
    assert page.get(f"/p/{player.token}").headers["location"] == "/participate/thanks"
    assert page.get("/participate/thanks").headers["location"] == "/participate/pairs"
    bad = page.post(
        "/participate/pairs",
        data={"csrf_token": csrf_token(page, "/participate/pairs"), "position": "0", "winner": "x"},
    )
    assert bad.status_code == 422 and "winner must be" in bad.text  # nothing stored
    for position in ("9" * 20, "1_0", "0.0"):  # past 64 bits (SQLite overflowed: a 500), or lax
        odd = page.post(
            "/participate/pairs",
            data={
                "csrf_token": csrf_token(page, "/participate/pairs"),
                "position": position,
                "winner": str(_pairs(player)[0]["left"]),
            },
        )
        assert odd.status_code == 404, position
    token = csrf_token(page, "/participate/pairs")  # a second tab's form, kept for later
    for n in range(total):
        shown = page.get("/participate/pairs")
        assert shown.status_code == 200 and f"Pair {n + 1} of {total}." in shown.text
        left = _pairs(player)[n]["left"]
        answered = page.post(
            "/participate/pairs",
            data={
                "csrf_token": csrf_token(page, "/participate/pairs"),
                "position": str(n),
                "winner": str(left),
            },
        )
        assert answered.status_code == 303 and answered.headers["location"] == "/participate/pairs"
    assert page.get("/participate/pairs").headers["location"] == "/participate/thanks"
    stale = page.post(  # a second tab's form, the other picture: the first answer is kept
        "/participate/pairs",
        data={
            "csrf_token": token,
            "position": "0",
            "winner": str(_pairs(player)[0]["right"]),
        },
    )
    assert stale.status_code == 409 and "your first answer is kept" in stale.text
    assert 'id="continue" href="/participate/pairs"' in stale.text
    assert page.get("/participate/thanks").status_code == 200
    assert [p["winner"] for p in _pairs(player)] == [p["left"] for p in _pairs(player)]
    undo = client.post("/api/participants/me/undo", headers=player.headers)  # pairs answered:
    assert undo.status_code == 409 and "after the bracket" in undo.json()["detail"]  # final
