"""Participant API: the next match, labels (201/200/409/422/404), resume, undo, bracket."""

from __future__ import annotations

import pytest
from sqlalchemy import func, select

from app.models import Label


def test_rounds_and_match_numbers_with_byes(invite) -> None:
    player = invite()  # five candidates: one first-round match, three byes
    seen = []
    while (match := player.next_match()) is not None:
        seen.append(
            (
                match["round"],
                match["match_number"],
                match["matches_in_round"],
                match["n_rounds"],
                match["progress"]["done"],
                match["progress"]["total"],
            )
        )
        assert match["a"]["candidate_id"] != match["b"]["candidate_id"]
        assert player.label(match["match_id"], match["b"]["candidate_id"]).status_code == 201
    assert seen == [(1, 1, 1, 3, 0, 4), (2, 1, 2, 3, 1, 4), (2, 2, 2, 3, 2, 4), (3, 1, 1, 3, 3, 4)]


def test_label_status_codes(invite) -> None:
    player = invite()
    match = player.next_match()
    a, b = match["a"]["candidate_id"], match["b"]["candidate_id"]
    outsider = ({0, 1, 2, 3, 4} - {a, b}).pop()
    first = player.label(match["match_id"], a, response_ms=1234)
    assert first.status_code == 201
    upcoming = player.next_match()  # the answer carries the next match: one round trip
    assert first.json() == {
        "match_id": match["match_id"],
        "winner": a,
        "tie": False,
        "created": True,
        "progress": {"done": 1, "total": 4},
        "finished": False,
        "next": upcoming,
    }
    again = player.label(match["match_id"], a)
    assert again.status_code == 200 and again.json()["created"] is False
    assert again.json()["next"] == upcoming
    other = player.label(match["match_id"], b)
    assert other.status_code == 409 and "already decided" in other.json()["detail"]
    assert player.label(match["match_id"], outsider).status_code == 422
    assert player.label(99_999_999, a).status_code == 404


def test_another_participants_match_is_hidden(client, invite) -> None:
    alice, bob = invite(), invite()
    match = alice.next_match()
    response = bob.label(match["match_id"], match["a"]["candidate_id"])
    assert response.status_code in (403, 404)
    assert alice.next_match() == match  # untouched
    assert client.get(f"/api/participants/{alice.id}/tree", headers=bob.headers).status_code == 403


@pytest.mark.parametrize(
    "body",
    [
        {},
        {"winner": "left"},
        {"winner": 1, "response_ms": -5},
        {"winner": 1, "extra": True},
        {"winner": 2**40},
        {"winner": None},
    ],
)
def test_bad_label_bodies_are_422(invite, body: dict) -> None:
    player = invite()
    match = player.next_match()
    response = player.client.post(
        f"/api/matches/{match['match_id']}/label", headers=player.headers, json=body
    )
    assert response.status_code == 422
    assert player.next_match() == match


@pytest.mark.parametrize("headers", [{}, {"Authorization": "Bearer not-a-token"}])
def test_participant_endpoints_need_an_invite_token(client, headers) -> None:
    for method, path in [
        ("GET", "/api/participants/me/next-match"),
        ("GET", "/api/participants/me"),
        ("POST", "/api/participants/me/undo"),
        ("POST", "/api/matches/1/label"),
    ]:
        response = client.request(method, path, headers=headers, json={"winner": 0})
        assert response.status_code == 401, path


def test_resume_where_they_left_off(client, invite) -> None:
    player = invite()
    first = player.next_match()
    player.label(first["match_id"], first["a"]["candidate_id"])
    upcoming = player.next_match()
    assert player.next_match() == upcoming  # asking again changes nothing
    client.cookies.clear()
    cookie = {"Cookie": f"acv_participant={player.token}"}  # the browser's way back in
    resumed = client.get("/api/participants/me/next-match", headers=cookie)
    assert resumed.json() == upcoming
    me = client.get("/api/participants/me", headers=cookie).json()
    assert (me["id"], me["progress"], me["finished"], me["can_undo"]) == (
        player.id,
        {"done": 1, "total": 4},
        False,
        True,
    )


def test_finished_bracket_answers_204(client, invite) -> None:
    player = invite()
    assert player.play() == 4
    last = client.get("/api/participants/me/bracket", headers=player.headers).json()["rounds"][-1][
        0
    ]
    again = player.label(last["match_id"], last["winner"])
    assert again.status_code == 200 and again.json()["next"] is None
    response = client.get("/api/participants/me/next-match", headers=player.headers)
    assert response.status_code == 204 and response.content == b""
    me = client.get("/api/participants/me", headers=player.headers).json()
    assert me["finished"] is True and me["progress"] == {"done": 4, "total": 4}


def test_undo_latest_reopens_it_even_after_the_final(client, invite) -> None:
    player = invite()
    player.play()
    final = client.get("/api/participants/me/bracket", headers=player.headers).json()["rounds"][-1][
        0
    ]
    undone = client.post("/api/participants/me/undo", headers=player.headers)
    assert undone.status_code == 200
    assert undone.json() == {
        "match_id": final["match_id"],
        "round": 3,
        "progress": {"done": 3, "total": 4},
    }
    assert player.next_match()["match_id"] == final["match_id"]
    assert client.get("/api/participants/me", headers=player.headers).json()["finished"] is False
    for _ in range(3):  # undo all the way back, latest first
        assert client.post("/api/participants/me/undo", headers=player.headers).status_code == 200
    assert player.next_match()["round"] == 1
    nothing = client.post("/api/participants/me/undo", headers=player.headers)
    assert nothing.status_code == 409 and "no label" in nothing.json()["detail"]


def test_undo_is_refused_once_the_participant_withdrew(client, invite) -> None:
    """Withdrawing keeps the answers as they were: undo would delete a stored label."""
    player = invite()
    match = player.next_match()
    assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    me = client.get("/api/participants/me", headers=player.headers).json()
    assert me["can_undo"] is True
    withdrawn = client.post(
        "/api/participants/me/withdraw", json={"withdraw": True}, headers=player.headers
    )
    assert withdrawn.status_code == 200, withdrawn.text
    refused = client.post("/api/participants/me/undo", headers=player.headers)
    assert refused.status_code == 410, refused.text
    assert (
        client.delete(f"/api/matches/{match['match_id']}/label", headers=player.headers).status_code
        == 410
    )
    assert client.get("/api/participants/me", headers=player.headers).json()["can_undo"] is False
    assert _labels_of(client, player.id) == 1  # the label is still stored


def _labels_of(client, participant_id: int) -> int:
    with client.app.state.runtime.sessions() as session:
        return session.scalar(
            select(func.count()).select_from(Label).where(Label.participant_id == participant_id)
        )


def test_undo_is_refused_once_a_later_match_depends_on_it(client, make_study, invite) -> None:
    four = make_study(n_candidates=4, seed=5)  # two first-round matches, then the final
    player = invite(four["id"])
    r1a, r1b = player.next_match(), None
    player.label(r1a["match_id"], r1a["a"]["candidate_id"])
    r1b = player.next_match()
    player.label(r1b["match_id"], r1b["b"]["candidate_id"])
    final = player.next_match()
    assert final["round"] == 2
    # The final exists but is undecided: undoing a first-round label removes it again.
    assert (
        client.delete(f"/api/matches/{r1a['match_id']}/label", headers=player.headers).status_code
        == 200
    )
    assert player.next_match()["match_id"] == r1a["match_id"]
    player.label(r1a["match_id"], r1a["b"]["candidate_id"])
    final = player.next_match()
    assert {final["a"]["candidate_id"], final["b"]["candidate_id"]} == {
        r1a["b"]["candidate_id"],
        r1b["b"]["candidate_id"],
    }
    player.label(final["match_id"], final["a"]["candidate_id"])
    refused = client.delete(f"/api/matches/{r1a['match_id']}/label", headers=player.headers)
    assert refused.status_code == 409 and "depends" in refused.json()["detail"]
    assert (
        client.delete(f"/api/matches/{final['match_id']}/label", headers=player.headers).status_code
        == 200
    )


def test_live_bracket_shows_decisions_so_far(client, invite) -> None:
    player = invite()
    first = player.next_match()
    player.label(first["match_id"], first["b"]["candidate_id"])
    rounds = client.get("/api/participants/me/bracket", headers=player.headers).json()["rounds"]
    assert [len(r) for r in rounds] == [4, 2, 1]
    byes = [c for c in rounds[0] if c["is_bye"]]
    assert len(byes) == 3 and all(c["winner"] == c["a"] and c["b"] is None for c in byes)
    decided = next(c for c in rounds[0] if c["match_id"] == first["match_id"])
    assert decided["winner"] == first["b"]["candidate_id"]
    assert all(c["winner"] is None for c in rounds[1] + rounds[2])
    assert all(c["match_id"] is not None for c in rounds[1])  # both players now known
    assert rounds[2][0]["a"] is None and rounds[2][0]["match_id"] is None
