"""Practice before the bracket (issue 28 §3) and the study options it comes with
(``allow_ties``, ``practice_pairs``): creation through the API and the form, practice states
that are not candidates, the practice API (nothing that tells the answer before it is given,
feedback after), the practice pages, and that nothing of practice is stored. SQLite and
PostgreSQL."""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from PIL import Image
from sqlalchemy import func, select

from app.models import Label, Match, Study
from app.settings import Settings
from app.studies.practice_states import MANIFEST, practice_folder, practice_states
from engine.practice import practice_plan
from tests.support.studies import Player, wait_ready
from tests.support.web import audit, browser, csrf_token, logged_in

PAIRS = 3  # two instructed pairs and one preference pair
BODY: dict[str, Any] = {"name": "practice", "env_id": "Hopper-v5", "n_candidates": 5, "seed": 13}
PRACTICE_RULE = "practice_pairs must be 0 (no practice) or 2 to 5"
ME = "/api/participants/me/practice"


@pytest.fixture(scope="module")
def practice_study(make_study: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    ready = make_study(**BODY, practice_pairs=PAIRS, allow_ties=True)
    assert ready["status"] == "ready", ready
    return ready


def _pairs(player: Player) -> list[dict[str, Any]]:
    response = player.client.get(ME, headers=player.headers)
    assert response.status_code == 200, response.text
    return response.json()


def _answer(player: Player, position: int, side: Any):
    return player.client.post(
        f"{ME}/{position}/answer", headers=player.headers, json={"side": side}
    )


def _labels_and_matches(client: TestClient, participant_id: int) -> tuple[int, int]:
    with client.app.state.runtime.sessions() as session:
        return (
            session.scalar(select(func.count()).where(Label.participant_id == participant_id)),
            session.scalar(select(func.count()).where(Match.participant_id == participant_id)),
        )


def _study_row(client: TestClient, study_id: int) -> Study:
    with client.app.state.runtime.sessions() as session:
        study = session.get(Study, study_id)
        assert study is not None
        session.expunge(study)
        return study


# --- the options at creation ----------------------------------------------------------------


def test_options_are_stored_and_shown(client, admin, practice_study, study) -> None:
    assert practice_study["allow_ties"] is True and practice_study["practice_pairs"] == PAIRS
    assert study["allow_ties"] is False and study["practice_pairs"] == 0  # the defaults
    listed = {s["id"]: s for s in client.get("/api/studies", headers=admin).json()}
    assert listed[practice_study["id"]]["practice_pairs"] == PAIRS


@pytest.mark.parametrize("bad", [1, 6, -1, 100])
def test_practice_pairs_out_of_range_are_422_with_the_rule(client, admin, bad: int) -> None:
    response = client.post("/api/studies", json=BODY | {"practice_pairs": bad}, headers=admin)
    assert response.status_code == 422
    assert f"{PRACTICE_RULE}, got {bad}" in str(response.json()["detail"])


@pytest.mark.parametrize(
    ("field", "bad"),
    [
        ("practice_pairs", True),
        ("practice_pairs", 2.0),
        ("practice_pairs", "2"),
        ("practice_pairs", None),
        ("allow_ties", "yes"),
        ("allow_ties", 1),
        ("allow_ties", "true"),
        ("allow_ties", None),
    ],
)
def test_options_of_the_wrong_type_are_422(client, admin, field: str, bad: Any) -> None:
    response = client.post("/api/studies", json=BODY | {field: bad}, headers=admin)
    assert response.status_code == 422
    assert field in str(response.json()["detail"])


def test_the_form_creates_a_study_with_the_options(client: TestClient) -> None:
    page = logged_in(client)
    new = page.get("/studies/new").text
    assert 'name="practice_pairs" type="number" min="0"' in new
    assert 'type="checkbox" id="allow_ties" name="allow_ties"' in new and audit(new) == []
    form = {k: str(v) for k, v in BODY.items()} | {
        "csrf_token": csrf_token(page, "/studies/new"),
        "p": "0.9",
        "sampling": "uniform",
        "instructions": "",
        "disagreement_pairs": "0",
    }
    ticked = page.post("/studies", data=form | {"practice_pairs": "2", "allow_ties": "true"})
    plain = page.post("/studies", data=form | {"practice_pairs": "0"})  # the box not ticked
    made = [
        wait_ready(client, int(r.headers["location"].rsplit("/", 1)[1])) for r in (ticked, plain)
    ]
    assert [(s["practice_pairs"], s["allow_ties"]) for s in made] == [(2, True), (0, False)]
    assert all(s["status"] == "ready" for s in made)


@pytest.mark.parametrize("bad", ["1", "6", "two"])
def test_the_form_shows_why_and_keeps_the_input(client: TestClient, bad: str) -> None:
    page = logged_in(client)
    form = {k: str(v) for k, v in BODY.items()} | {
        "csrf_token": csrf_token(page, "/studies/new"),
        "p": "0.9",
        "seed": "1",
        "sampling": "uniform",
        "instructions": "",
        "allow_ties": "true",
    }
    refused = page.post("/studies", data=form | {"practice_pairs": bad})
    assert refused.status_code == 422 and 'id="practice_pairs-error"' in refused.text
    if bad != "two":
        assert f"{PRACTICE_RULE}, got {bad}" in refused.text
    assert f'value="{bad}"' in refused.text  # the input kept
    assert re.search(
        r'name="allow_ties" value="true"\s+aria-describedby="ties-help"\s+checked', refused.text
    )


# --- practice states ------------------------------------------------------------------------


def test_practice_states_are_not_among_the_candidates(
    client, admin, settings: Settings, practice_study
) -> None:
    states = practice_states(settings.images_dir, _study_row(client, practice_study["id"]))
    assert states is not None and len(states) == 2 * PAIRS
    candidates = client.get(f"/api/studies/{practice_study['id']}/candidates", headers=admin)
    assert len(candidates.json()) == BODY["n_candidates"]  # none added to the candidates
    for qpos in states.qpos:
        assert not any(np.allclose(qpos, c["qpos"]) for c in candidates.json())
    assert all(states.image(i, marked=m).is_file() for i in range(2 * PAIRS) for m in (False, True))


# --- the practice API -----------------------------------------------------------------------


def test_pairs_tell_nothing_of_the_answer_until_it_is_given(client, practice_study, invite) -> None:
    player = invite(practice_study["id"])
    pairs = _pairs(player)
    assert [p["position"] for p in pairs] == list(range(PAIRS))
    assert sorted(p["kind"] for p in pairs) == ["instructed", "instructed", "preference"]
    for p in pairs:
        assert set(p) == {"position", "total", "kind", "prompt", "left_url", "right_url"}
        assert p["total"] == PAIRS
        assert p["left_url"] == f"{ME}/{p['position']}/image?side=left"
        assert p["right_url"] == f"{ME}/{p['position']}/image?side=right"
        assert ("marker" in p["prompt"]) == (p["kind"] == "instructed")
    assert _pairs(player) == pairs  # seeded: the same again


def test_feedback_after_each_answer(client, practice_study, invite) -> None:
    player = invite(practice_study["id"])
    for pair in _pairs(player):
        left = _answer(player, pair["position"], "left")
        assert left.status_code == 200, left.text
        said = left.json()
        assert said["position"] == pair["position"] and said["kind"] == pair["kind"]
        if pair["kind"] == "preference":
            assert said["correct"] is None and said["marker"] is None
            assert "no right answer" in said["feedback"]
            continue
        marker = said["marker"]
        assert said["correct"] is (marker == "left")
        right = _answer(player, pair["position"], "right").json()
        assert right["correct"] is (marker == "right") and right["marker"] == marker
        for answer in (said, right):
            verdict = "Right" if answer["correct"] else "Not quite"
            assert answer["feedback"] == f"{verdict}: the marker was on the {marker}."


def test_pictures_show_the_marker_on_one_side_of_instructed_pairs(
    client, settings: Settings, practice_study, invite
) -> None:
    player = invite(practice_study["id"])
    states = practice_states(settings.images_dir, _study_row(client, practice_study["id"]))
    assert states is not None
    plan = practice_plan(PAIRS, seed=BODY["seed"], participant_id=player.id)
    for pair in plan:
        for side, state in (("left", pair.left), ("right", pair.right)):
            image = client.get(f"{ME}/{pair.position}/image?side={side}", headers=player.headers)
            assert image.status_code == 200 and image.headers["content-type"] == "image/jpeg"
            assert image.headers["cache-control"] == "private, no-cache"
            assert Image.open(io.BytesIO(image.content)).size == (480, 480)
            expected = states.image(state, marked=pair.marked == side).read_bytes()
            assert image.content == expected
    marked = states.image(0, marked=True).read_bytes()
    assert marked != states.image(0, marked=False).read_bytes()


@pytest.mark.parametrize(
    ("path", "body", "status"),
    [
        (f"{ME}/{PAIRS}/answer", {"side": "left"}, 404),  # no such pair
        (f"{ME}/5/answer", {"side": "left"}, 422),  # never a pair
        (f"{ME}/-1/answer", {"side": "left"}, 422),
        (f"{ME}/0/answer", {"side": "up"}, 422),
        (f"{ME}/0/answer", {"side": "left", "extra": 1}, 422),
        (f"{ME}/0/answer", {}, 422),
        (f"{ME}/0/answer", None, 422),
        (f"{ME}/x/answer", {"side": "left"}, 422),
    ],
)
def test_bad_answers_are_4xx_json(
    client, practice_study, invite, path: str, body: Any, status: int
) -> None:
    player = invite(practice_study["id"])
    response = client.post(path, headers=player.headers, json=body)
    assert response.status_code == status and response.json()["detail"]


@pytest.mark.parametrize(
    ("query", "status"),
    [(f"{PAIRS}/image?side=left", 404), ("0/image?side=up", 422), ("0/image", 422)],
)
def test_bad_picture_requests_are_4xx_json(
    client, practice_study, invite, query: str, status: int
) -> None:
    player = invite(practice_study["id"])
    response = client.get(f"{ME}/{query}", headers=player.headers)
    assert response.status_code == status and response.json()["detail"]


def test_practice_needs_an_invite_token(client, practice_study, admin) -> None:
    assert client.get(ME).status_code == 401
    assert client.get(ME, headers=admin).status_code == 401  # the researcher is no participant
    assert client.post(f"{ME}/0/answer", json={"side": "left"}).status_code == 401


def test_practice_stores_nothing_and_ends_with_the_first_label(
    client, practice_study, invite
) -> None:
    player = invite(practice_study["id"])
    before = _labels_and_matches(client, player.id)
    for pair in _pairs(player):
        for side in ("left", "right", "left"):
            assert _answer(player, pair["position"], side).status_code == 200
    assert _labels_and_matches(client, player.id) == before == (0, before[1])
    me = client.get("/api/participants/me", headers=player.headers).json()
    assert me["progress"]["done"] == 0
    match = player.next_match()
    assert player.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    assert _pairs(player) == []  # a participant with a label never sees practice again
    assert _answer(player, 0, "left").status_code == 404


def test_no_practice_in_a_study_without_it(client, study, invite) -> None:
    player = invite()
    assert _pairs(player) == []
    assert _answer(player, 0, "left").status_code == 404


# --- the pages ------------------------------------------------------------------------------


def test_the_pages_go_through_practice_to_the_bracket(client, practice_study, invite) -> None:
    player = invite(practice_study["id"])
    page = browser(client)
    assert page.get(f"/p/{player.token}").headers["location"] == "/participate"
    instructions = page.get("/participate").text
    assert 'id="start" href="/participate/practice"' in instructions
    assert f"{PAIRS} practice pairs" in instructions
    url, seen = "/participate/practice", []
    for position in range(PAIRS):
        shown = page.get(url)
        assert shown.status_code == 200 and audit(shown.text) == []
        assert f"Practice pair {position + 1} of {PAIRS}." in shown.text
        assert f'src="{ME}/{position}/image?side=left"' in shown.text
        assert 'id="practice-left"' in shown.text and 'id="feedback"' not in shown.text
        assert page.get(url).text == shown.text  # a reload shows the same pair
        answered = page.get("/participate/practice", params={"pair": position, "chose": "right"})
        assert answered.status_code == 200 and 'id="feedback"' in answered.text
        assert 'id="practice-left"' not in answered.text
        seen.append(re.search(r'id="feedback"[^>]*>\s*([^<]+?)\s*</p>', answered.text)[1])
        url = re.search(r'id="next" href="([^"]+)"', answered.text)[1].replace("&amp;", "&")
    assert url == "/participate/label"
    assert sum(s.startswith(("Right: ", "Not quite: ")) for s in seen) == 2
    assert sum("no right answer" in s for s in seen) == 1
    assert _labels_and_matches(client, player.id)[0] == 0


@pytest.mark.parametrize("query", ["?pair=9", "?pair=-1", "?pair=x", "?chose=up", f"?pair={PAIRS}"])
def test_bad_practice_urls_are_error_pages(client, practice_study, invite, query: str) -> None:
    player = invite(practice_study["id"])
    page = browser(client)
    page.get(f"/p/{player.token}")
    response = page.get(f"/participate/practice{query}")
    assert response.status_code == 404 and "text/html" in response.headers["content-type"]


def test_the_pages_skip_practice_where_there_is_none(client, study, practice_study, invite) -> None:
    for player, labelled in ((invite(), False), (invite(practice_study["id"]), True)):
        if labelled:
            match = player.next_match()
            player.label(match["match_id"], match["a"]["candidate_id"])
        page = browser(client)
        page.get(f"/p/{player.token}")
        if not labelled:
            assert 'id="start" href="/participate/label"' in page.get("/participate").text
        skipped = page.get("/participate/practice")
        assert skipped.status_code == 303 and skipped.headers["location"] == "/participate/label"


def test_missing_practice_states_skip_practice(
    client, settings: Settings, make_study, invite
) -> None:
    """A data dir that lost the pictures (or another database's) must not block anyone."""
    ready = make_study(**(BODY | {"seed": 14}), practice_pairs=2)
    player = invite(ready["id"])
    assert len(_pairs(player)) == 2
    manifest = practice_folder(settings.images_dir, ready["id"]) / MANIFEST
    manifest.rename(manifest.with_suffix(".moved"))
    assert _pairs(player) == []
    page = browser(client)
    page.get(f"/p/{player.token}")
    assert 'id="start" href="/participate/label"' in page.get("/participate").text


def test_a_participant_who_withdrew_gets_the_ended_page_not_practice(
    client, practice_study, invite
) -> None:
    player = invite(practice_study["id"])
    page = browser(client)
    assert page.get(f"/p/{player.token}").status_code == 303
    assert page.get("/participate/practice").status_code == 200  # before: practice
    gone = client.post(
        "/api/participants/me/withdraw", json={"withdraw": True}, headers=player.headers
    )
    assert gone.status_code == 200, gone.text
    after = page.get("/participate/practice")
    assert after.status_code == 303 and after.headers["location"] == "/participate/ended"
