"""Freed seats and a code for every outcome (issue 45 §1-2), on SQLite and PostgreSQL.

A study's open link takes a time limit per participant. A participant past it, unfinished,
is timed out: no code, their seat goes to the next newcomer, and they can do nothing more
(coming back with the same platform ids shows them so, never a second seat). A participant
who withdraws frees their seat at once and gets the decline code; their labels are kept in
the database and left out of every export. Time passing is simulated by moving a member's
deadline into the past in the database (the clock the server reads moved on).
"""

from __future__ import annotations

import csv
import io
import re
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import func, select, update

from app.db import make_engine, make_sessions, writing
from app.models import Member, utcnow
from app.recruiting.seats import within_time
from tests.support.crowd import configure, joined_player, start, visit, visitor
from tests.support.studies import Player
from tests.support.surveys import paper_body
from tests.support.web import ADMIN, csrf_token

LIMITED = {"max_participants": 1, "time_limit_min": 30, "completion_code": "DONE-1"}
CODES = {"decline_code": "NOPE-2", "redirect_url": "https://example.org/done?cc={code}"}


@pytest.fixture
def study_id(make_study: Callable[..., dict[str, Any]]) -> int:
    return make_study(n_candidates=4)["id"]


def _expire(settings: Any, member_id: int) -> None:
    """Move the member's deadline a second into the past (their time ran out)."""
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session, writing(session):
            past = utcnow() - timedelta(seconds=1)
            session.execute(update(Member).where(Member.id == member_id).values(deadline_at=past))
    finally:
        engine.dispose()


def _acting(settings: Any, study_id: int) -> int:
    """Open-link members of the study who hold a seat and may still act."""
    engine = make_engine(settings.sqlalchemy_url)
    try:
        with make_sessions(engine)() as session:
            return session.scalar(
                select(func.count(Member.id)).where(
                    Member.collection_kind == "study",
                    Member.collection_id == study_id,
                    Member.via_link.is_(True),
                    Member.finished_at.is_(None),
                    within_time(utcnow()),
                )
            )
    finally:
        engine.dispose()


def _join(client: TestClient, link: dict[str, Any], pid: str) -> tuple[TestClient, Any]:
    return visit(client, link, f"?PROLIFIC_PID={pid}&SESSION_ID=s-{pid}")


def _person(client: TestClient, member_id: int) -> dict[str, Any]:
    return client.get(f"/api/participants/{member_id}", headers=ADMIN).json()


def _joined(client: TestClient, study_id: int) -> int:
    return client.get(f"/api/studies/{study_id}/crowd", headers=ADMIN).json()["joined"]


def _label_one(player: Player) -> Any:
    match = player.next_match()
    assert match is not None
    return player.label(match["match_id"], match["a"]["candidate_id"])


def test_a_seat_freed_by_time_goes_to_a_newcomer(client, settings, study_id) -> None:
    link = configure(client, study_id, **LIMITED)
    browser, answer = _join(client, link, "w1")
    first = joined_player(client, browser, answer)
    assert _person(client, first.id)["deadline_at"] is not None
    assert "is full" in _join(client, link, "w2")[1].text  # one seat, taken
    _expire(settings, first.id)
    newcomer = joined_player(client, *_join(client, link, "w2"))
    assert _joined(client, study_id) == 1 and newcomer.id != first.id
    timed_out = _person(client, first.id)
    assert (timed_out["outcome"], timed_out["code"]) == ("timed_out", None)
    assert _label_one(first).status_code == 410  # out of time: no more labels
    back = browser.get(f"/s/{link['slug']}?PROLIFIC_PID=w1&SESSION_ID=s-w1", follow_redirects=True)
    assert back.status_code == 200 and "Your time is over" in back.text
    assert "completion-code" not in back.text  # no code for a time-out
    assert _joined(client, study_id) == 1  # never a second seat


def test_the_time_limit_is_said_before_it_runs_out(client, study_id) -> None:
    """The welcome page says how long one has once started; the instructions, how long is
    left (they said "come back at any time", and the first word of the limit was "your
    place was given to someone else")."""
    link = configure(client, study_id, **LIMITED)
    browser = visitor(client)
    welcome = browser.get(f"/s/{link['slug']}")
    assert "you have 30 minutes to finish" in welcome.text
    joined = start(browser, welcome)
    instructions = browser.get(joined.headers["location"], follow_redirects=True)
    assert re.search(r"You have about (29|30) minutes\s+left to finish", instructions.text)
    assert "come back through your link at any time" not in instructions.text
    unlimited = configure(client, study_id, max_participants=5)  # the same link, no limit now
    again = visitor(client).get(f"/s/{unlimited['slug']}")
    assert "minutes to finish" not in again.text


def test_one_who_finished_the_bracket_in_time_answers_the_check_after_it(
    client, settings, study_id
) -> None:
    """The time limit frees the seats of those who leave unfinished; one who finished the
    bracket in time (``finished_at`` set) may still answer the consistency check after it
    and gets the completion code (the check was refused, and the thank-you page sent them
    back to it for ever)."""
    link = configure(client, study_id, **LIMITED, consistency_check=True)
    browser, answer = _join(client, link, "slow")
    player = joined_player(client, browser, answer)
    player.play()
    _expire(settings, player.id)
    assert browser.get("/participate/thanks").headers["location"] == "/participate/check"
    page = browser.get("/participate/check")
    winner = re.search(r'name="winner" value="(\d+)"', page.text)
    assert page.status_code == 200 and winner, page.text
    data = {"csrf_token": csrf_token(browser, "/participate/check"), "winner": winner.group(1)}
    answered = browser.post("/participate/check", data=data | {"stimulus": "still"})
    assert answered.status_code == 303, answered.text
    thanks = browser.get("/participate/thanks")
    assert thanks.status_code == 200 and "DONE-1" in thanks.text
    assert (_person(client, player.id)["outcome"], _person(client, player.id)["code"]) == (
        "finished",
        "DONE-1",
    )


def test_a_timed_out_participant_and_newcomers_at_once_never_overfill(
    client, settings, study_id
) -> None:
    link = configure(client, study_id, **LIMITED)
    first = joined_player(client, *_join(client, link, "late"))
    _expire(settings, first.id)
    start = threading.Barrier(4)

    def go(i: int) -> httpx.Response:
        start.wait(timeout=60)
        if i == 0:
            return _label_one(first)
        return _join(client, link, f"new{i}")[1]

    with ThreadPoolExecutor(4) as pool:
        late, *newcomers = pool.map(go, range(4))
    assert late.status_code == 410
    assert sorted(r.status_code for r in newcomers) == [200, 200, 303]  # one seat, two full
    assert _joined(client, study_id) == 1
    assert _acting(settings, study_id) == 1


def test_withdrawing_frees_the_seat_keeps_the_labels_and_leaves_them_out(client, study_id) -> None:
    link = configure(client, study_id, **LIMITED, **CODES)
    player = joined_player(client, *_join(client, link, "w3"))
    assert _label_one(player).status_code == 201
    withdraw = "/api/participants/me/withdraw"
    for bad in ({}, {"withdraw": False}, {"withdraw": "true"}, {"withdraw": 1}):
        refused = client.post(withdraw, json=bad, headers=player.headers)
        assert refused.status_code == 422, (bad, refused.text)
    assert _joined(client, study_id) == 1  # nothing changed
    gone = client.post(withdraw, json={"withdraw": True}, headers=player.headers)
    assert gone.status_code == 200, gone.text
    assert gone.json() == {
        "outcome": "withdrawn",
        "code": "NOPE-2",
        "redirect_url": "https://example.org/done?cc=NOPE-2",
    }
    assert _joined(client, study_id) == 0
    again = client.post(withdraw, json={"withdraw": True}, headers=player.headers)
    assert again.status_code == 410
    assert _label_one(player).status_code == 410
    for query in ("", "?include_excluded=true"):  # never exported, whatever is asked
        labels = client.get(f"/api/studies/{study_id}/labels.csv{query}", headers=ADMIN).text
        rows = list(csv.DictReader(io.StringIO(labels)))
        assert all(r["participant_id"] != str(player.id) for r in rows)
    assert _person(client, player.id)["outcome"] == "withdrawn"


def test_withdrawing_twice_from_the_page_shows_the_ended_page_again(client, study_id) -> None:
    """A double click or a reload of the withdraw form: the ended page with its code, not an
    error page without it."""
    link = configure(client, study_id, **LIMITED, **CODES)
    browser, _ = _join(client, link, "w4")
    token = csrf_token(browser, "/participate/withdraw")
    form = {"csrf_token": token, "decision": "withdraw"}
    for _ in range(2):
        done = browser.post("/participate/withdraw", data=form)
        assert done.status_code == 303 and done.headers["location"] == "/participate/ended"
    ended = browser.get("/participate/ended")
    assert ended.status_code == 200 and "NOPE-2" in ended.text


def test_one_who_withdrew_cannot_choose_to_share(client, study_id) -> None:
    """Their answers are left out of everything, so a sharing choice would mean nothing: the
    instructions page's form sends them to the ended page, the API answers 410, and the
    stored choice stays as it was."""
    link = configure(client, study_id, **LIMITED, **CODES)
    browser, response = _join(client, link, "w5")
    player = joined_player(client, browser, response)
    token = csrf_token(browser, "/participate/withdraw")
    form = {"csrf_token": token, "decision": "withdraw"}
    assert browser.post("/participate/withdraw", data=form).status_code == 303
    shared = browser.post("/participate/share", data={"csrf_token": token, "share": "on"})
    assert shared.status_code == 303 and shared.headers["location"] == "/participate/ended"
    path = "/api/participants/me/share-consent"
    refused = client.put(path, json={"share": True}, headers=player.headers)
    assert refused.status_code == 410 and "withdrew" in refused.json()["detail"]
    assert _person(client, player.id)["share_consent"] is False


def test_declining_shows_the_decline_code_and_the_way_back(client, study_id) -> None:
    link = configure(client, study_id, consent_text="We keep your choices.", **CODES)
    browser = TestClient(client.app, follow_redirects=False)
    token = csrf_token(browser, f"/s/{link['slug']}?PROLIFIC_PID=d1")
    declined = browser.post(f"/s/{link['slug']}", data={"decision": "decline", "csrf_token": token})
    assert declined.status_code == 200 and "You declined" in declined.text
    assert "NOPE-2" in declined.text
    assert 'href="https://example.org/done?cc=NOPE-2"' in declined.text


def test_each_outcome_has_its_code_and_a_survey_link_takes_no_time_limit(client, study_id) -> None:
    link = configure(client, study_id, **{**LIMITED, "max_participants": 5}, **CODES)
    finisher = joined_player(client, *_join(client, link, "f1"))
    finisher.play()
    listed = {
        p["id"]: p
        for p in client.get(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    }
    assert (listed[finisher.id]["outcome"], listed[finisher.id]["code"]) == ("finished", "DONE-1")
    export = client.get(f"/api/studies/{study_id}/export/labels.csv", headers=ADMIN).text
    mine = [
        r for r in csv.DictReader(io.StringIO(export)) if r["participant_id"] == str(finisher.id)
    ]
    assert mine and all((r["outcome"], r["code"]) == ("finished", "DONE-1") for r in mine)
    invited = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    assert (_person(client, invited["id"])["code"]) is None  # invited: no platform code
    survey = client.post("/api/surveys", json=_survey_body(client, study_id), headers=ADMIN)
    assert survey.status_code == 201, survey.text
    timed = {"enabled": True, "max_participants": 5, "time_limit_min": 30}
    refused = client.put(f"/api/surveys/{survey.json()['id']}/crowd", json=timed, headers=ADMIN)
    assert refused.status_code in (400, 422) and "time_limit_min" in refused.text
    for bad in (0, 10_081, True, 1.5):
        body = {**LIMITED, "time_limit_min": bad, "enabled": True}
        answer = client.put(f"/api/studies/{study_id}/crowd", json=body, headers=ADMIN)
        assert answer.status_code == 422, (bad, answer.text)


def _survey_body(client: TestClient, study_id: int) -> dict[str, Any]:
    people = [
        p["id"]
        for p in client.get(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
        if p["finished"]
    ]
    trees = [{"kind": "participant", "participant_id": people[0]}] * 2
    return paper_body(*trees)
