"""Exports: a finished participant's acv.tree/1 document, study trees, and the labels CSV."""

from __future__ import annotations

import csv
import io

import numpy as np

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
