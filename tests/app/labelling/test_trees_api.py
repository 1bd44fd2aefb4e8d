"""Exports: a finished participant's acv.tree/1 document, study trees, and the labels CSV."""

from __future__ import annotations

import csv
import io

import numpy as np
from sqlalchemy import select

from app.db import make_engine, make_sessions
from app.models import Label, Match
from engine.envs import env_model
from engine.pipeline import run_tournament
from engine.teachers import standing_score
from engine.treefile import tree_from_json, tree_to_json


def _standing_chooser(client, admin, study_id: int):
    """Pick like the engine's `standing` teacher: higher score wins, ties to side a."""
    cands = client.get(f"/api/studies/{study_id}/candidates", headers=admin).json()
    scores = standing_score(np.array([c["qpos"] for c in cands]), env_model("Hopper-v5"))

    def choose(match: dict) -> int:
        a, b = match["a"]["candidate_id"], match["b"]["candidate_id"]
        return b if scores[b] > scores[a] else a

    return choose


def test_tree_equals_the_engines_for_the_same_decisions(client, admin, study, invite) -> None:
    player = invite()
    player.play(_standing_chooser(client, admin, study["id"]))
    response = client.get(f"/api/participants/{player.id}/tree", headers=admin)
    assert response.status_code == 200
    doc = tree_from_json(response.json())  # a valid acv.tree/1 document
    expected = run_tournament(
        env_id="Hopper-v5", n_candidates=5, p=0.9, seed=study["seed"], teacher="standing"
    )
    got, want = tree_to_json(doc), tree_to_json(expected)
    assert got["judge"] == f"participant:{player.id}"
    for key in ("schema", "env_id", "seed", "p", "first_round", "matches", "tree"):
        assert got[key] == want[key], key
    assert [c["qpos"] for c in got["candidates"]] == [c["qpos"] for c in want["candidates"]]


def test_participant_sees_own_tree_only_when_finished(client, invite) -> None:
    player = invite()
    unfinished = client.get(f"/api/participants/{player.id}/tree", headers=player.headers)
    assert unfinished.status_code == 409 and "not finished" in unfinished.json()["detail"]
    player.play()
    own = client.get(f"/api/participants/{player.id}/tree", headers=player.headers)
    assert own.status_code == 200 and own.json()["schema"] == "acv.tree/1"
    assert client.get(f"/api/participants/{player.id}/tree").status_code == 401
    assert client.get("/api/participants/99999999/tree", headers=player.headers).status_code == 403


def test_researcher_gets_unknown_participant_as_404(client, admin) -> None:
    assert client.get("/api/participants/99999999/tree", headers=admin).status_code == 404
    assert client.get("/api/participants/99999999", headers=admin).status_code == 404


def test_study_trees_list_finished_participants(client, admin, study, invite) -> None:
    done, pending = invite(), invite()
    done.play()
    trees = client.get(f"/api/studies/{study['id']}/trees", headers=admin).json()
    ids = [t["participant_id"] for t in trees]
    assert done.id in ids and pending.id not in ids
    assert all(t["tree"]["schema"] == "acv.tree/1" for t in trees)


def test_labels_csv(client, admin, study, invite) -> None:
    player = invite()
    match = player.next_match()
    player.label(match["match_id"], match["b"]["candidate_id"], response_ms=321)
    player.play()
    response = client.get(f"/api/studies/{study['id']}/labels.csv", headers=admin)
    assert response.headers["content-type"].startswith("text/csv")
    assert "attachment" in response.headers["content-disposition"]
    rows = [
        r
        for r in csv.DictReader(io.StringIO(response.text))
        if r["participant_id"] == str(player.id)
    ]
    assert len(rows) == 4
    first = rows[0]
    assert (first["match_id"], first["winner"], first["response_ms"], first["round"]) == (
        str(match["match_id"]),
        str(match["b"]["candidate_id"]),
        "321",
        "1",
    )
    assert all(int(r["response_ms"]) >= 0 for r in rows)  # estimated when not sent
    assert all(r["labelled_at"].endswith("+00:00") for r in rows)
    assert all(r["tie"] == "False" for r in rows)


def _tie_first_match(settings, participant_id: int) -> tuple[int, int, int]:
    """Mark the participant's round-1 label "can't tell" in the database, as the app stores
    a tie (the coin's winner kept); returns its match's id, slot and loser."""
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            label, match = session.execute(
                select(Label, Match)
                .join(Match, Match.id == Label.match_id)
                .where(Match.participant_id == participant_id, Match.round == 1)
            ).one()
            label.tie = True
            session.commit()
            return match.id, match.slot, match.b if label.winner == match.a else match.a
    finally:
        engine.dispose()


def test_a_tied_label_is_a_tie_in_the_tree_and_the_csv(
    client, admin, settings, study, invite
) -> None:
    player = invite()
    player.play()
    match_id, slot, loser = _tie_first_match(settings, player.id)
    tree = client.get(f"/api/participants/{player.id}/tree", headers=admin).json()
    assert [m.get("tie") for m in tree["matches"]] == [True] + [None] * 3  # round 1 first
    doc = tree_from_json(tree)
    assert doc.ties == {(1, slot)}
    assert doc.tree.nodes[loser].height == 1  # raised to the tied match's height
    assert doc.tree.nodes[loser].reward == 0.0  # r_e * 1 - r_b, as its winner after the match
    listed = client.get(f"/api/studies/{study['id']}/trees", headers=admin).json()
    assert next(t["tree"] for t in listed if t["participant_id"] == player.id) == tree
    csv_text = client.get(f"/api/studies/{study['id']}/labels.csv", headers=admin).text
    ties = {
        r["match_id"]: r["tie"]
        for r in csv.DictReader(io.StringIO(csv_text))
        if r["participant_id"] == str(player.id)
    }
    assert ties.pop(str(match_id)) == "True" and set(ties.values()) == {"False"}
