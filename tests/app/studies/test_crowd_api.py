"""Crowd-ready studies (issue 14): the open link, external ids, consent, the maximum, the
rate limit, sides, quality flags, agreement and exports, on SQLite and PostgreSQL."""

from __future__ import annotations

import csv
import io
import json
import re
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pyarrow.parquet as pq
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from app.core.auth import PARTICIPANT_COOKIE
from app.db import make_engine, upgrade
from app.http.ratelimit import LoginLimiter
from app.labelling.label_export import COLUMNS
from app.labelling.sides import a_on_left
from tests.support.crowd import SETTINGS, configure, joined_player, visit, visitor
from tests.support.postgres import empty_database
from tests.support.studies import Player
from tests.support.web import ADMIN, audit, csrf_token, logged_in


@pytest.fixture(autouse=True)
def fresh_join_limit(client: TestClient) -> None:
    """Each test starts with no joins counted against the test client's address."""
    client.app.state.join_limiter = LoginLimiter(30)


@pytest.fixture(scope="module")
def four(make_study) -> dict[str, Any]:
    """A 4-candidate study: two first-round matches, then the final (no byes)."""
    return make_study(n_candidates=4, seed=11)


def participants_of(client: TestClient, study_id: int) -> list[dict[str, Any]]:
    return client.get(f"/api/studies/{study_id}/participants", headers=ADMIN).json()


def test_settings_round_trip_with_defaults(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"])
    assert link["external_params"] == ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"]
    assert link["speed_threshold_ms"] == 800 and link["joined"] == 0
    assert link["url"] == f"http://testserver/s/{link['slug']}"
    again = configure(client, study["id"], max_participants=7)
    assert again["slug"] == link["slug"] and again["max_participants"] == 7
    assert client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json() == again


@pytest.mark.parametrize(
    "bad",
    [
        {"max_participants": True},
        {"max_participants": "5"},
        {"max_participants": 0},
        {"speed_threshold_ms": False},
        {"speed_threshold_ms": 1.5},
        {"enabled": 1},
        {"external_params": ["ok", "no spaces"]},
        {"external_params": []},
        {"redirect_url": "javascript:alert(1)"},
        {"unknown": 1},
    ],
)
def test_bad_settings_are_4xx_json(client, study, bad) -> None:
    response = client.put(f"/api/studies/{study['id']}/crowd", json=SETTINGS | bad, headers=ADMIN)
    assert response.status_code == 422 and "detail" in response.json(), response.text


def test_a_bad_open_link_form_shows_the_study_page_again_as_typed(client, study) -> None:
    """The researcher's form on the study page: a bad field is a 422 page, the study's own,
    with the form as it was sent and what is wrong; nothing is saved."""
    page = logged_in(client)
    path = f"/studies/{study['id']}"
    before = client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json()
    form = {"csrf_token": csrf_token(page, path), "enabled": "on", "max_participants": "9"}
    form |= {"external_params": "PROLIFIC_PID, study-id", "speed_threshold_ms": "700"}
    form |= {"consent_text": "We keep your choices.", "consistency_check": "on"}
    bad = page.post(f"{path}/crowd", data=form)
    assert bad.status_code == 422 and 'id="crowd-error" role="alert">Not saved:' in bad.text
    assert "external_params" in bad.text and 'value="PROLIFIC_PID, study-id"' in bad.text
    assert "We keep your choices.</textarea>" in bad.text and 'value="700"' in bad.text
    assert re.search(r'id="consistency_check"\s+checked', bad.text) and audit(bad.text) == []
    assert client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json() == before


def test_settings_are_the_researchers(client, study) -> None:
    assert client.put(f"/api/studies/{study['id']}/crowd", json=SETTINGS).status_code == 401
    assert visitor(client).get(f"/api/studies/{study['id']}/quality").status_code == 401


def test_same_prolific_pid_resumes_one_participant(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"])
    query = "?PROLIFIC_PID=abc123&STUDY_ID=s1&SESSION_ID=x1&other=ignored"
    first, response = visit(client, link, query)
    player = joined_player(client, first, response)
    player.label(player.next_match()["match_id"], player.next_match()["left"])
    assert visit(client, link, "?PROLIFIC_PID=abc123&SESSION_ID=x2")[1].status_code == 409
    second, again = visit(client, link, query)  # the platform's link again: same attempt
    assert again.status_code == 303 and again.headers["location"] == "/participate/label"
    assert second.cookies[PARTICIPANT_COOKIE] == player.token
    people = participants_of(client, study["id"])
    assert [p["id"] for p in people] == [player.id]
    assert client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json()["joined"] == 1
    export = client.get(f"/api/studies/{study['id']}/export/labels.jsonl", headers=ADMIN)
    row = json.loads(export.text.splitlines()[0])
    assert row["external_id"] == "abc123"
    assert row["external_ids"] == {"PROLIFIC_PID": "abc123", "STUDY_ID": "s1", "SESSION_ID": "x1"}


def test_same_pid_at_once_gives_one_participant(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"])
    with ThreadPoolExecutor(6) as pool:
        answers = list(
            pool.map(
                lambda _: visit(client, link, "?PROLIFIC_PID=twin&STUDY_ID=s&SESSION_ID=t"),
                range(6),
            )
        )
    tokens = {browser.cookies[PARTICIPANT_COOKIE] for browser, r in answers if r.status_code == 303}
    assert len(tokens) == 1 and all(r.status_code == 303 for _, r in answers)
    assert len(participants_of(client, study["id"])) == 1


def test_full_study_admits_exactly_the_maximum_at_once(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"], max_participants=3)
    with ThreadPoolExecutor(8) as pool:
        answers = list(pool.map(lambda _: visit(client, link), range(10)))
    codes = sorted(r.status_code for _, r in answers)
    assert codes == [200] * 7 + [303] * 3
    assert all("This study is full" in r.text for _, r in answers if r.status_code == 200)
    assert len(participants_of(client, study["id"])) == 3
    _, late = visit(client, link, "?PROLIFIC_PID=late")
    assert late.status_code == 200 and "This study is full" in late.text


def test_returning_browser_without_ids_keeps_its_participant(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"])
    browser, first = visit(client, link)
    token = browser.cookies[PARTICIPANT_COOKIE]
    assert browser.get(f"/s/{link['slug']}").status_code == 303
    assert browser.cookies[PARTICIPANT_COOKIE] == token
    assert len(participants_of(client, study["id"])) == 1


def test_decline_stores_nothing_but_a_count(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"], consent_text="We store your choices.")
    browser, page = visit(client, link, "?PROLIFIC_PID=nope")
    assert page.status_code == 200 and "We store your choices." in page.text
    csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
    declined = browser.post(
        f"/s/{link['slug']}",
        data={"csrf_token": csrf, "decision": "decline", "PROLIFIC_PID": "nope"},
    )
    assert declined.status_code == 200 and "You declined" in declined.text
    assert PARTICIPANT_COOKIE not in browser.cookies
    assert participants_of(client, study["id"]) == []
    export = client.get(f"/api/studies/{study['id']}/export/labels.csv", headers=ADMIN)
    assert export.text.count("\n") == 1  # the header only
    state = client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json()
    assert (state["declines"], state["joined"]) == (1, 0)
    agreed = browser.post(
        f"/s/{link['slug']}", data={"csrf_token": csrf, "decision": "agree", "PROLIFIC_PID": "yes"}
    )
    assert agreed.status_code == 303 and agreed.headers["location"] == "/participate"
    assert [p["id"] for p in participants_of(client, study["id"])] != []


def test_a_member_who_declines_later_goes_on_and_is_not_counted(client, make_study) -> None:
    """The consent form posted again after joining (a second tab, the back button): declining
    there would show a decline code to someone who stays a member, with their answers."""
    study = make_study()
    link = configure(client, study["id"], consent_text="We store your choices.")
    browser, page = visit(client, link)
    csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
    form = {"csrf_token": csrf}
    assert browser.post(f"/s/{link['slug']}", data=form | {"decision": "agree"}).status_code == 303
    again = browser.post(f"/s/{link['slug']}", data=form | {"decision": "decline"})
    assert again.status_code == 303 and again.headers["location"] == "/participate"
    odd = browser.post(f"/s/{link['slug']}", data=form)  # no decision: neither, so refused
    assert odd.status_code == 422 and "agree or decline" in odd.text
    state = client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json()
    assert (state["declines"], state["joined"]) == (0, 1)


def test_a_double_click_on_agree_makes_one_member(client, make_study) -> None:
    """The second post of the consent form arrives without the cookie the first one sets:
    the form's one-time key resumes the member the first one made (it took a second seat)."""
    study = make_study()
    link = configure(client, study["id"], consent_text="We store your choices.")
    browser, page = visit(client, link)
    twin = visitor(client)  # the same page's second request: its cookies, not the answer's
    twin.cookies.update(browser.cookies)
    form = {"csrf_token": page.text.split('name="csrf_token" value="')[1].split('"')[0]}
    form["join_key"] = page.text.split('name="join_key" value="')[1].split('"')[0]
    first = browser.post(f"/s/{link['slug']}", data=form | {"decision": "agree"})
    second = twin.post(f"/s/{link['slug']}", data=form | {"decision": "agree"})
    assert first.status_code == second.status_code == 303
    assert browser.cookies[PARTICIPANT_COOKIE] == twin.cookies[PARTICIPANT_COOKIE]
    state = client.get(f"/api/studies/{study['id']}/crowd", headers=ADMIN).json()
    assert state["joined"] == 1 and len(participants_of(client, study["id"])) == 1
    _, again = visit(client, link)  # a new visit is a new form, a new key
    assert again.text.split('name="join_key" value="')[1].split('"')[0] != form["join_key"]


def test_consent_post_needs_the_csrf_token(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"], consent_text="Consent?")
    browser, _ = visit(client, link)
    assert browser.post(f"/s/{link['slug']}", data={"decision": "agree"}).status_code == 403
    assert participants_of(client, study["id"]) == []


def test_closed_unknown_and_overlong_links(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"], enabled=False)
    assert visit(client, link)[1].status_code == 410
    assert visitor(client).get("/s/no-such-link").status_code == 404
    configure(client, study["id"])
    response = visit(client, link, "?PROLIFIC_PID=" + "x" * 201)[1]
    assert response.status_code == 422 and "PROLIFIC_PID" in response.text


def test_joins_are_rate_limited_per_client(client, make_study) -> None:
    study = make_study()
    link = configure(client, study["id"])
    client.app.state.join_limiter = LoginLimiter(2)
    codes = [visit(client, link)[1].status_code for _ in range(3)]
    assert codes == [303, 303, 429]
    assert len(participants_of(client, study["id"])) == 2


def _play(player: Player, choose) -> None:
    while (match := player.next_match()) is not None:
        assert player.label(match["match_id"], choose(match), response_ms=500).status_code == 201


def test_sides_are_seeded_stored_and_reported(client, make_study, settings) -> None:
    study = make_study(n_candidates=8, seed=5)
    link = configure(client, study["id"])
    player = joined_player(client, *visit(client, link))
    seen = []
    while (match := player.next_match()) is not None:
        assert match["left"] in (match["a"]["candidate_id"], match["b"]["candidate_id"])
        seen.append(match["left"] == match["a"]["candidate_id"])
        player.label(match["match_id"], match["left"], response_ms=500)
    assert len(seen) == 7
    engine = make_engine(settings.sqlalchemy_url)
    try:  # each match's side is the seeded coin of (study seed, participant, round, slot)
        with engine.connect() as conn:
            stored = conn.execute(
                text("SELECT round, slot, a_left FROM matches WHERE participant_id = :p"),
                {"p": player.id},
            ).all()
    finally:
        engine.dispose()
    assert len(stored) == 7 and [bool(left) for _, _, left in sorted(stored)] == [
        a_on_left(seed=5, participant_id=player.id, rnd=r, slot=s) for r, s, _ in sorted(stored)
    ]
    quality = client.get(f"/api/studies/{study['id']}/quality", headers=ADMIN).json()
    mine = next(p for p in quality["participants"] if p["participant_id"] == player.id)
    # 7 left choices of 7: two-sided binomial p = 2 * 0.5**7 = 0.015625.
    assert mine["position_bias"] == {
        "labels": 7,
        "left": 7,
        "left_share": 1.0,
        "p_value": pytest.approx(0.015625),
    }
    assert mine["median_response_ms"] == 500 and mine["fast"] is True
    assert mine["flags"] == ["position_bias", "fast"]
    assert mine["reliability"] == pytest.approx(0.25) and mine["reliability_checks"] == 0
    rows = [
        json.loads(line)
        for line in client.get(
            f"/api/studies/{study['id']}/export/labels.jsonl", headers=ADMIN
        ).text.splitlines()
    ]
    assert {r["side"] for r in rows} == {"left"} and all(r["winner"] == r["left"] for r in rows)


def test_agreement_and_alpha_match_hand_computed_values(client, four) -> None:
    link = configure(client, four["id"])
    players = [joined_player(client, *visit(client, link)) for _ in range(3)]
    low = lambda m: min(m["a"]["candidate_id"], m["b"]["candidate_id"])  # noqa: E731
    high = lambda m: max(m["a"]["candidate_id"], m["b"]["candidate_id"])  # noqa: E731
    for player, choose in zip(players, (low, low, high), strict=True):
        _play(player, choose)
    body = client.get(f"/api/studies/{four['id']}/agreement", headers=ADMIN).json()
    p1, p2, p3 = (p.id for p in players)
    pairs = {(p["a"], p["b"]): (p["shared"], p["agreement"]) for p in body["pairs"]}
    # P1 and P2 decide the same three pairs alike; P3 shares only the first round with them
    # and decides both of its pairs the other way.
    assert pairs == {(p1, p2): (3, 1.0), (p1, p3): (2, 0.0), (p2, p3): (2, 0.0)}
    assert body["mean_agreement"] == pytest.approx(1 / 3)
    # Units (0: lower id won): [0,0,1], [0,0,1], [0,0]; coincidences o00=4, o01=o10=2,
    # o11=0; n=8, Do = 4/8, De = 2*6*2/(8*7): alpha = 1 - 0.5 / (24/56) = -1/6.
    assert body["shared_pairs"] == 3
    assert body["krippendorff_alpha"] == pytest.approx(-1 / 6)
    rewards = {
        c["id"]: c["env_reward"]
        for c in client.get(f"/api/studies/{four['id']}/candidates", headers=ADMIN).json()
    }
    good = {t["participant_id"]: t["agreement"] for t in body["teachers"] if t["teacher"] == "good"}
    rows = [
        json.loads(x)
        for x in client.get(
            f"/api/studies/{four['id']}/export/labels.jsonl", headers=ADMIN
        ).text.splitlines()
    ]
    for pid in (p1, p3):
        mine = [r for r in rows if r["participant_id"] == pid]
        best = [max((r["left"], r["right"]), key=rewards.__getitem__) for r in mine]
        expected = sum(b == r["winner"] for b, r in zip(best, mine, strict=True)) / 3
        assert good[pid] == pytest.approx(expected)
    assert {t["teacher"] for t in body["teachers"]} == {"good", "standing"}


def test_exports_have_one_row_per_label(client, four) -> None:
    link = configure(client, four["id"])
    player = joined_player(client, *visit(client, link, "?PROLIFIC_PID=exp"))
    _play(player, lambda m: m["b"]["candidate_id"])
    base = f"/api/studies/{four['id']}/export/labels"
    rows = [json.loads(x) for x in client.get(base + ".jsonl", headers=ADMIN).text.splitlines()]
    mine = [r for r in rows if r["participant_id"] == player.id]
    assert [r["round"] for r in mine] == [1, 1, 2]
    assert set(mine[0]) == {
        "study_id",
        "participant_id",
        "external_id",
        "external_ids",
        "kind",
        "match_id",
        "round",
        "left",
        "right",
        "winner",
        "side",
        "response_ms",
        "shown_at",
        "labelled_at",
        "flags",
        "tie",
        "stimulus",
        "reliability",
        "gold_right",
        "gold_asked",
        "excluded",
        "outcome",
        "code",
    }
    assert {(r["outcome"], r["code"]) for r in mine} == {("finished", None)}  # no code set
    assert {r["kind"] for r in mine} == {"bracket"}  # this study asks no disagreement pairs
    assert all(r["response_ms"] == 500 and r["shown_at"] < r["labelled_at"] for r in mine)
    assert all(r["side"] == ("left" if r["winner"] == r["left"] else "right") for r in mine)
    table = list(csv.DictReader(io.StringIO(client.get(base + ".csv", headers=ADMIN).text)))
    assert len(table) == len(rows) and table[-1]["external_id"] == "exp"
    parquet = pq.read_table(io.BytesIO(client.get(base + ".parquet", headers=ADMIN).content))
    assert parquet.column_names == list(COLUMNS)  # every format has every column
    assert parquet.num_rows == len(rows) and parquet.column("winner").to_pylist() == [
        r["winner"] for r in rows
    ]
    assert client.get(base + ".xlsx", headers=ADMIN).status_code == 404


def test_consistency_check_repeats_a_pair_swapped(client, make_study) -> None:
    study = make_study(n_candidates=4, seed=2)
    link = configure(
        client,
        study["id"],
        consistency_check=True,
        completion_code="C0DE",
        redirect_url="https://example.org/done?cc=C0DE",
    )
    browser, response = visit(client, link)
    player = joined_player(client, browser, response)
    first = player.next_match()
    _play(player, lambda m: m["left"])
    assert browser.get("/participate/thanks").headers["location"] == "/participate/check"
    page = browser.get("/participate/check")
    assert page.status_code == 200 and "not part of your bracket" in page.text
    left = int(page.text.split('id="check-left"')[0].rsplit('value="', 1)[1].split('"')[0])
    csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
    assert (
        browser.post("/participate/check", data={"csrf_token": csrf, "winner": "99"}).status_code
        == 422
    )
    # The left picture now is the right one before: choosing it again contradicts the label
    # when that pair was decided by side (always left), so the check reports "differs".
    done = browser.post("/participate/check", data={"csrf_token": csrf, "winner": str(left)})
    assert done.headers["location"] == "/participate/thanks"
    # A second tab (or the back button) sends the other picture: the first answer is kept,
    # and the page says so and leads on.
    other = int(page.text.split('id="check-right"')[0].rsplit('value="', 1)[1].split('"')[0])
    stale = browser.post("/participate/check", data={"csrf_token": csrf, "winner": str(other)})
    assert stale.status_code == 409 and "your first answer is kept" in stale.text
    assert 'id="continue" href="/participate/thanks"' in stale.text
    thanks = browser.get("/participate/thanks")
    assert "C0DE" in thanks.text and "https://example.org/done?cc=C0DE" in thanks.text
    quality = client.get(f"/api/studies/{study['id']}/quality", headers=ADMIN).json()
    mine = next(p for p in quality["participants"] if p["participant_id"] == player.id)
    assert mine["consistency_agrees"] is False and "inconsistent" in mine["flags"]
    # MACE competence after one contradicted check: E[max(0, 2X - 1)], X ~ Beta(1, 2).
    assert mine["reliability"] == pytest.approx(1 / 12) and mine["reliability_checks"] == 1
    assert first is not None
    # The check was asked of this bracket and the code shown: the bracket is final now.
    me = client.get("/api/participants/me", headers=player.headers).json()
    assert me["can_undo"] is False
    undo = client.post("/api/participants/me/undo", headers=player.headers)
    assert undo.status_code == 409 and "after the bracket" in undo.json()["detail"]


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_migration_0006_keeps_matches_and_labels(request, tmp_path, backend: str) -> None:
    """0006 adds columns in place (no table copy whose drop would cascade to labels)."""
    url = empty_database(request, tmp_path, backend)
    upgrade(url, "0005")
    engine = make_engine(url)
    with engine.begin() as conn:
        for statement in (
            "INSERT INTO studies (id, name, env_id, n_candidates, p, seed, sampling, "
            "instructions, status, created_at) VALUES (1, 's', 'Hopper-v5', 2, 0.9, 0, "
            "'uniform', '', 'ready', CURRENT_TIMESTAMP)",
            "INSERT INTO participants (id, study_id, token, token_hash, created_at) "
            "VALUES (1, 1, 't', 'h', CURRENT_TIMESTAMP)",
            "INSERT INTO matches (id, participant_id, round, slot, a, b, created_at) "
            "VALUES (1, 1, 1, 0, 0, 1, CURRENT_TIMESTAMP)",
            "INSERT INTO labels (id, match_id, participant_id, winner, created_at) "
            "VALUES (1, 1, 1, 0, CURRENT_TIMESTAMP)",
        ):
            conn.execute(text(statement))
    engine.dispose()
    upgrade(url)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            assert conn.execute(text("SELECT a_left FROM matches")).scalars().all() == [True]
            assert conn.execute(text("SELECT chose_left FROM labels")).scalars().all() == [None]
    finally:
        engine.dispose()


def test_left_side_is_a_seeded_fair_coin() -> None:
    flips = [
        a_on_left(seed=5, participant_id=p, rnd=1, slot=s) for p in range(50) for s in range(8)
    ]
    assert flips == [
        a_on_left(seed=5, participant_id=p, rnd=1, slot=s) for p in range(50) for s in range(8)
    ]
    assert 150 < sum(flips) < 250  # 400 flips of a fair coin (deterministic: fixed inputs)
