"""Gold items, the qualification gate, exclusion and "can't tell" through the REST API
(issue 28 §1 and §3), on SQLite and PostgreSQL: gold items are shown among the bracket's
matches and never enter it; gold accuracy has its Clopper-Pearson interval; the gate flags
and, when asked, excludes; a tie advances by the seeded coin and is counted, never compared.
Bad input gets a 422 and changes nothing."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.labelling import gold_placement
from tests.support.crowd import configure
from tests.support.studies import Player
from tests.support.web import ADMIN

N = 8  # candidates: 7 bracket matches, gold positions 1..6


@pytest.fixture(scope="module")
def tie_study(make_study: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    return make_study(n_candidates=N, allow_ties=True)


@pytest.fixture(scope="module")
def gold_study(make_study: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    return make_study(n_candidates=N, seed=5)


def _add_gold(client: TestClient, study_id: int, **body: Any):
    return client.post(f"/api/studies/{study_id}/gold", json=body, headers=ADMIN)


@pytest.fixture(scope="module")
def gold_items(client: TestClient, gold_study: dict[str, Any]) -> list[dict[str, Any]]:
    sid = gold_study["id"]
    made = [
        _add_gold(client, sid, kind="pair", a=0, b=1, answer=1),
        _add_gold(client, sid, kind="instructed", a=2, b=3, answer=2),
    ]
    assert all(r.status_code == 201 for r in made), [r.text for r in made]
    return [r.json() for r in made]


def _walk(player: Player, gold_answer: Callable[[dict[str, Any]], int]) -> list[dict[str, Any]]:
    """Play the bracket (``a`` wins), answering gold items with ``gold_answer``; returns the
    gold prompts seen, with the bracket's progress when each came."""
    seen = []
    while (match := player.next_match()) is not None:
        if match["gold"] is not None:
            seen.append(match)
            sent = player.answer_gold(match["gold"]["item_id"], gold_answer(match))
            assert sent.status_code == 201, sent.text
        else:
            assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    return seen


def _walk_until_stopped(player: Player, gold_answer: Callable[[dict[str, Any]], int]) -> int:
    """:func:`_walk`, until the bracket is finished or the study stops the player (410);
    returns the labels stored."""
    labelled = 0
    while (match := player.next_match()) is not None:
        if match["gold"] is not None:
            sent = player.answer_gold(match["gold"]["item_id"], gold_answer(match))
            assert sent.status_code == 201, sent.text
            continue
        sent = player.label(match["match_id"], match["a"]["candidate_id"])
        if sent.status_code == 410:
            assert "this study has ended for you" in sent.json()["detail"]
            return labelled
        assert sent.status_code == 201, sent.text
        labelled += 1
    return labelled


def _quality_of(client: TestClient, study_id: int, participant_id: int) -> dict[str, Any]:
    q = client.get(f"/api/studies/{study_id}/quality", headers=ADMIN).json()
    return next(p for p in q["participants"] if p["participant_id"] == participant_id)


def test_gold_items_come_among_the_matches_and_never_enter_the_bracket(
    client: TestClient, gold_study: dict[str, Any], gold_items: list[dict[str, Any]], invite
) -> None:
    player = invite(gold_study["id"])
    seen = _walk(
        player, lambda m: {0: 1, 2: 2}[min(m["a"]["candidate_id"], m["b"]["candidate_id"])]
    )
    assert sorted(m["gold"]["item_id"] for m in seen) == sorted(g["id"] for g in gold_items)
    places = gold_placement.positions(
        n_candidates=N, count=2, seed=gold_study["seed"], participant_id=player.id
    )
    assert sorted(m["progress"]["done"] for m in seen) == places
    assert all(1 <= p <= N - 2 for p in places)
    instructed = next(m for m in seen if m["gold"]["prompt"])
    marked = [s for s in (instructed["a"], instructed["b"]) if "marker=true" in s["image_url"]]
    assert [s["candidate_id"] for s in marked] == [2]
    tree = client.get(f"/api/participants/{player.id}/tree", headers=ADMIN).json()
    assert len(tree["matches"]) == N - 1  # the bracket alone
    mine = _quality_of(client, gold_study["id"], player.id)
    assert (mine["gold_right"], mine["gold_asked"]) == (2, 2)
    assert mine["gold_interval"][1] == pytest.approx(1.0)
    assert mine["reliability_checks"] == 2
    exported = client.get(f"/api/studies/{gold_study['id']}/export/labels.jsonl", headers=ADMIN)
    rows = [json.loads(line) for line in exported.text.splitlines()]
    assert {
        (r["gold_right"], r["gold_asked"]) for r in rows if r["participant_id"] == player.id
    } == {(2, 2)}


def test_a_due_gold_item_cannot_be_skipped(
    client: TestClient, gold_study: dict[str, Any], gold_items: list[dict[str, Any]], invite
) -> None:
    player = invite(gold_study["id"])
    while (match := player.next_match())["gold"] is None:
        assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    done = match["progress"]["done"]
    skipped = player.label(match["match_id"], match["a"]["candidate_id"])
    assert skipped.status_code == 409 and "check pair" in skipped.json()["detail"]
    assert player.next_match()["progress"]["done"] == done
    answered = player.answer_gold(match["gold"]["item_id"], match["a"]["candidate_id"])
    assert answered.status_code == 201 and answered.json()["next"]["match_id"] == match["match_id"]


def test_a_gold_item_cannot_be_answered_before_it_is_due(
    client: TestClient, gold_study: dict[str, Any], gold_items: list[dict[str, Any]], invite
) -> None:
    """Answering ahead would take the check out of its place among the matches (issue 45
    §6): a 409 that stores nothing; once shown, the item is answered as usual."""
    player = invite(gold_study["id"])
    first = player.next_match()
    for item in gold_items:
        early = player.answer_gold(item["id"], item["answer"])
        assert early.status_code == 409, early.text
        assert f"gold item {item['id']} is not due yet" in early.json()["detail"]
    assert player.next_match() == first
    assert _quality_of(client, gold_study["id"], player.id)["gold_asked"] == 0
    seen = _walk(player, lambda match: match["a"]["candidate_id"])
    assert sorted(m["gold"]["item_id"] for m in seen) == sorted(g["id"] for g in gold_items)


def test_the_marker_is_drawn_on_the_image(client: TestClient, gold_study: dict[str, Any]) -> None:
    url = f"/api/studies/{gold_study['id']}/candidates/2/image"
    plain, marked = client.get(url, headers=ADMIN), client.get(url + "?marker=true", headers=ADMIN)
    assert plain.status_code == marked.status_code == 200
    assert marked.headers["content-type"] == plain.headers["content-type"]
    assert marked.content != plain.content


@pytest.mark.parametrize("excludes", [False, True])
def test_the_gate_flags_a_careless_participant_and_excludes_only_when_asked(
    client: TestClient,
    gold_study: dict[str, Any],
    gold_items: list[dict[str, Any]],
    invite,
    excludes: bool,
) -> None:
    sid = gold_study["id"]
    configure(client, sid, gold_gate=0.9, gate_excludes=excludes)
    wrong = {g["id"]: ({g["a"], g["b"]} - {g["answer"]}).pop() for g in gold_items}
    careless = invite(sid)
    labelled = _walk_until_stopped(careless, lambda m: wrong[m["gold"]["item_id"]])
    # an excluding gate stops them after their second failed gold item; flags only: never
    assert (labelled < N - 1) is excludes
    person = client.get(f"/api/participants/{careless.id}", headers=ADMIN).json()
    assert person["outcome"] == ("failed_gate" if excludes else "finished")
    mine = _quality_of(client, sid, careless.id)
    # 0 of 2 right: the exact 95% upper bound is 1 - 0.025 ** (1 / 2) = 0.842 < 0.9
    assert mine["gold_interval"][1] == pytest.approx(1 - 0.025**0.5)
    assert "below_gate" in mine["flags"]
    assert mine["excluded"] is excludes
    if excludes:
        assert mine["exclusion_reason"].startswith("gold gate: 0 of 2")

    def rows(query: str = "") -> int:
        text = client.get(f"/api/studies/{sid}/labels.csv{query}", headers=ADMIN).text
        return sum(
            r["participant_id"] == str(careless.id) for r in csv.DictReader(io.StringIO(text))
        )

    assert rows("?include_excluded=true") == labelled  # kept
    assert rows() == (0 if excludes else N - 1)  # left out of the export when excluded
    configure(client, sid, gold_gate=None, gate_excludes=False)


def test_the_researcher_excludes_and_includes_again(
    client: TestClient, study: dict[str, Any], invite
) -> None:
    person = invite()
    url = f"/api/participants/{person.id}/exclusion"
    out = client.put(url, json={"excluded": True, "reason": "spoke to a friend"}, headers=ADMIN)
    assert out.status_code == 200, out.text
    assert (out.json()["excluded"], out.json()["exclusion_reason"]) == (True, "spoke to a friend")
    back = client.put(url, json={"excluded": False}, headers=ADMIN).json()
    assert (back["excluded"], back["exclusion_reason"]) == (False, "included by the researcher")
    assert client.put(url, json={"excluded": True}).status_code == 401


@pytest.mark.parametrize(
    "body",
    [
        {"excluded": 1},
        {"excluded": "yes"},
        {},
        {"excluded": True, "reason": ""},
        {"excluded": True, "extra": 1},
    ],
)
def test_bad_exclusions_are_refused_and_change_nothing(
    client: TestClient, study: dict[str, Any], invite, body: dict[str, Any]
) -> None:
    person = invite()
    url = f"/api/participants/{person.id}/exclusion"
    refused = client.put(url, json=body, headers=ADMIN)
    assert refused.status_code == 422 and refused.json()["detail"], refused.text
    assert client.get(f"/api/participants/{person.id}", headers=ADMIN).json()["excluded"] is False


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ({"kind": "pair", "a": 0, "b": 0, "answer": 0}, "two different candidates"),
        ({"kind": "pair", "a": 0, "b": 1, "answer": 2}, "answer must be 0 or 1"),
        ({"kind": "pair", "a": 0, "b": 7, "answer": 0}, "candidate 7 is not one of study"),
        ({"kind": "marker", "a": 0, "b": 1, "answer": 0}, "kind"),
        ({"kind": "pair", "a": False, "b": 1, "answer": 1}, "integer"),
        ({"kind": "pair", "a": 0, "b": 1}, "answer"),
    ],
)
def test_bad_gold_items_are_refused_and_change_nothing(
    client: TestClient, study: dict[str, Any], body: dict[str, Any], says: str
) -> None:
    # ``study`` has 5 candidates (0..4): candidate 7 belongs only to larger studies
    before = client.get(f"/api/studies/{study['id']}/gold", headers=ADMIN).json()
    refused = _add_gold(client, study["id"], **body)
    assert refused.status_code == 422, refused.text
    assert says in str(refused.json()["detail"])
    assert client.get(f"/api/studies/{study['id']}/gold", headers=ADMIN).json() == before


def test_a_gold_item_somebody_answered_is_kept(
    client: TestClient, gold_study: dict[str, Any], gold_items: list[dict[str, Any]], invite
) -> None:
    sid, item = gold_study["id"], gold_items[0]
    _walk(invite(sid), lambda m: m["a"]["candidate_id"])  # answers every gold item
    assert client.delete(f"/api/studies/{sid}/gold/{item['id']}", headers=ADMIN).status_code == 409
    spare = _add_gold(client, sid, kind="pair", a=4, b=5, answer=4).json()
    assert client.delete(f"/api/studies/{sid}/gold/{spare['id']}", headers=ADMIN).status_code == 204
    assert client.delete(f"/api/studies/{sid}/gold/{spare['id']}", headers=ADMIN).status_code == 404


@pytest.mark.parametrize("gate", [1.5, -0.1, True, "0.5"])
def test_a_gate_outside_0_1_is_refused(
    client: TestClient, gold_study: dict[str, Any], gate: Any
) -> None:
    sid = gold_study["id"]
    refused = client.put(
        f"/api/studies/{sid}/crowd", json={"enabled": True, "gold_gate": gate}, headers=ADMIN
    )
    assert refused.status_code == 422, refused.text
    assert client.get(f"/api/studies/{sid}/quality", headers=ADMIN).json()["gold_gate"] is None


def test_a_tie_advances_by_the_seeded_coin_and_is_counted_not_compared(
    client: TestClient, tie_study: dict[str, Any], invite
) -> None:
    player = invite(tie_study["id"])
    first = player.next_match()
    assert first["allow_ties"] is True
    tied = client.post(
        f"/api/matches/{first['match_id']}/label", json={"tie": True}, headers=player.headers
    )
    assert tied.status_code == 201, tied.text
    body = tied.json()
    assert body["tie"] is True and body["winner"] in (
        first["a"]["candidate_id"],
        first["b"]["candidate_id"],
    )
    again = client.post(
        f"/api/matches/{first['match_id']}/label", json={"tie": True}, headers=player.headers
    )
    assert again.status_code == 200 and again.json()["winner"] == body["winner"]
    other = first["a"]["candidate_id"] + first["b"]["candidate_id"] - body["winner"]
    assert player.label(first["match_id"], other).status_code == 409
    player.play()
    mine = _quality_of(client, tie_study["id"], player.id)
    assert mine["ties"] == 1
    assert mine["position_bias"]["labels"] == N - 2  # the tie chose no side
    tree = client.get(f"/api/participants/{player.id}/tree", headers=ADMIN).json()
    assert [m.get("tie", False) for m in tree["matches"]].count(True) == 1


@pytest.mark.parametrize(
    "body",
    [{"tie": True, "winner": 0}, {"tie": False}, {}, {"tie": 1}, {"tie": "true"}],
)
def test_bad_ties_are_refused_and_change_nothing(
    client: TestClient, tie_study: dict[str, Any], invite, body: dict[str, Any]
) -> None:
    player = invite(tie_study["id"])
    match = player.next_match()
    refused = client.post(
        f"/api/matches/{match['match_id']}/label", json=body, headers=player.headers
    )
    assert refused.status_code == 422 and refused.json()["detail"], refused.text
    assert player.next_match()["progress"]["done"] == 0


def test_a_tie_where_the_study_does_not_allow_it_is_refused(
    client: TestClient, study: dict[str, Any], invite
) -> None:
    player = invite()
    match = player.next_match()
    assert match["allow_ties"] is False
    refused = client.post(
        f"/api/matches/{match['match_id']}/label", json={"tie": True}, headers=player.headers
    )
    assert refused.status_code == 422
    assert "does not allow" in refused.json()["detail"]
    assert player.next_match()["match_id"] == match["match_id"]
