"""Crowd-ready surveys (issue 14): a survey's open link ``/q/<slug>``, external ids, consent,
the maximum under concurrent first visits, the rate limit, completion and exports, and the
survey page's open-link form, on SQLite and PostgreSQL."""

from __future__ import annotations

import csv
import io
import json
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.http.ratelimit import LoginLimiter
from app.surveys.respond import RESPONDENT_COOKIE
from tests.support.crowd import join
from tests.support.surveys import (
    Respondent,
    invite,
    paper_answers,
    paper_body,
    participant_trees,
)
from tests.support.web import ADMIN, audit, browser, csrf_token, logged_in

SETTINGS = {"enabled": True, "max_participants": 50}
PID = "?PROLIFIC_PID=abc123&STUDY_ID=s1&SESSION_ID=x1&other=ignored"


@pytest.fixture(autouse=True)
def fresh_join_limit(client: TestClient) -> None:
    """Each test starts with no joins counted against the test client's address."""
    client.app.state.join_limiter = LoginLimiter(30)


@pytest.fixture(scope="module")
def trees(client: TestClient, study: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Two finished participants' trees, for the surveys' stimuli."""
    return participant_trees(client, study["id"])  # type: ignore[return-value]


@pytest.fixture
def survey(client: TestClient, trees) -> dict[str, Any]:
    """A new paper survey (one stimulus and the attention check: two screens)."""
    response = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()


def configure(client: TestClient, survey_id: int, **options: Any) -> dict[str, Any]:
    response = client.put(f"/api/surveys/{survey_id}/crowd", json=SETTINGS | options, headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


def state(client: TestClient, survey_id: int) -> dict[str, Any]:
    return client.get(f"/api/surveys/{survey_id}/crowd", headers=ADMIN).json()


def visit(client: TestClient, link: dict[str, Any], query: str = "") -> tuple[TestClient, Any]:
    """A first visit from a browser of its own (an empty cookie jar)."""
    page = browser(client)
    return page, join(page, f"/q/{link['slug']}{query}")


def joined(client: TestClient, page: TestClient, response: Any) -> Respondent:
    assert response.status_code == 303 and response.headers["location"] == "/survey"
    return Respondent(client, 0, page.cookies[RESPONDENT_COOKIE], "")


def respondents(client: TestClient, survey_id: int) -> list[dict[str, Any]]:
    return client.get(f"/api/surveys/{survey_id}/respondents", headers=ADMIN).json()


def answer_all(person: Respondent) -> None:
    while (screen := person.screen()) is not None:
        assert person.answer(screen["position"], paper_answers(screen)).status_code == 201


def test_settings_round_trip_with_counts(client, survey) -> None:
    assert client.get(f"/api/surveys/{survey['id']}/crowd", headers=ADMIN).status_code == 404
    link = configure(client, survey["id"])
    assert link["external_params"] == ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"]
    assert link["url"] == f"http://testserver/q/{link['slug']}"
    assert (link["joined"], link["declines"], link["completed"]) == (0, 0, 0)
    again = configure(client, survey["id"], max_participants=7, completion_code="C0DE")
    assert again["slug"] == link["slug"] and again["max_participants"] == 7
    assert state(client, survey["id"]) == again
    assert client.put(f"/api/surveys/{survey['id']}/crowd", json=SETTINGS).status_code == 401
    assert client.put("/api/surveys/999999/crowd", json=SETTINGS, headers=ADMIN).status_code == 404


@pytest.mark.parametrize(
    ("field", "bad"),
    [
        ("max_participants", True),
        ("max_participants", -1),
        ("max_participants", 0),
        ("max_participants", 1.5),
        ("max_participants", "5"),
        ("redirect_url", "javascript:alert(1)"),
        ("redirect_url", "ftp://example.org/done"),
        ("enabled", 1),
        ("external_params", ["ok", "no spaces"]),
        ("external_params", []),
        ("unknown", 1),
    ],
)
def test_bad_settings_are_422_json_naming_the_field(client, survey, field, bad) -> None:
    response = client.put(
        f"/api/surveys/{survey['id']}/crowd", json=SETTINGS | {field: bad}, headers=ADMIN
    )
    assert response.status_code == 422, response.text
    assert field in json.dumps(response.json()["detail"])


def test_maximum_below_those_joined_is_refused(client, survey) -> None:
    link = configure(client, survey["id"])
    for pid in ("one", "two"):
        visit(client, link, f"?PROLIFIC_PID={pid}")
    response = client.put(
        f"/api/surveys/{survey['id']}/crowd", json=SETTINGS | {"max_participants": 1}, headers=ADMIN
    )
    assert response.status_code == 422 and "max_participants" in response.text


def test_same_prolific_pid_resumes_one_respondent(client, survey) -> None:
    link = configure(client, survey["id"])
    first, response = visit(client, link, PID)
    person = joined(client, first, response)
    screen = person.screen()
    assert person.answer(screen["position"], paper_answers(screen)).status_code == 201
    assert visit(client, link, "?PROLIFIC_PID=abc123&SESSION_ID=x2")[1].status_code == 409
    second, again = visit(client, link, PID)  # the platform's link again: same attempt
    assert again.status_code == 303 and again.headers["location"] == "/survey"
    assert second.cookies[RESPONDENT_COOKIE] == person.token
    [row] = respondents(client, survey["id"])
    assert row["external_id"] == "abc123"
    assert row["external_ids"] == {"PROLIFIC_PID": "abc123", "STUDY_ID": "s1", "SESSION_ID": "x1"}
    assert state(client, survey["id"])["joined"] == 1
    answer_all(person)
    jsonl = client.get(f"/api/surveys/{survey['id']}/answers.jsonl", headers=ADMIN).text
    records = [json.loads(line) for line in jsonl.splitlines()]
    assert records and all(r["external_id"] == "abc123" for r in records)
    assert records[0]["external_ids"] == row["external_ids"]
    text = client.get(f"/api/surveys/{survey['id']}/answers.csv", headers=ADMIN).text
    rows = list(csv.DictReader(io.StringIO(text)))
    assert len(rows) == len(records) and rows[0]["external_id"] == "abc123"
    assert json.loads(rows[0]["external_ids"]) == row["external_ids"]


def test_same_pid_at_once_gives_one_respondent(client, survey) -> None:
    link = configure(client, survey["id"])
    with ThreadPoolExecutor(6) as pool:
        answers = list(
            pool.map(lambda _: visit(client, link, PID.replace("abc123", "twin")), range(6))
        )
    assert all(r.status_code == 303 for _, r in answers)
    assert len({page.cookies[RESPONDENT_COOKIE] for page, _ in answers}) == 1
    assert len(respondents(client, survey["id"])) == 1
    assert state(client, survey["id"])["joined"] == 1


def test_full_survey_admits_exactly_the_maximum_at_once(client, survey) -> None:
    link = configure(client, survey["id"], max_participants=3)
    with ThreadPoolExecutor(8) as pool:
        answers = list(pool.map(lambda _: visit(client, link), range(10)))
    assert sorted(r.status_code for _, r in answers) == [200] * 7 + [303] * 3
    assert all("This survey is full" in r.text for _, r in answers if r.status_code == 200)
    assert len(respondents(client, survey["id"])) == 3
    assert state(client, survey["id"])["joined"] == 3
    _, late = visit(client, link, "?PROLIFIC_PID=late")
    assert late.status_code == 200 and "This survey is full" in late.text
    invite(client, survey["id"])  # invites are not seats of the open link
    assert state(client, survey["id"])["joined"] == 3


def test_decline_stores_no_respondent_and_no_answers(client, survey) -> None:
    link = configure(client, survey["id"], consent_text="We store your answers.")
    page, consent = visit(client, link, "?PROLIFIC_PID=nope")
    assert consent.status_code == 200 and "We store your answers." in consent.text
    assert f'action="/q/{link["slug"]}"' in consent.text and audit(consent.text) == []
    csrf = consent.text.split('name="csrf_token" value="')[1].split('"')[0]
    declined = page.post(
        f"/q/{link['slug']}", data={"csrf_token": csrf, "decision": "decline", "PROLIFIC_PID": "x"}
    )
    assert declined.status_code == 200 and "You declined" in declined.text
    assert RESPONDENT_COOKIE not in page.cookies
    assert respondents(client, survey["id"]) == []
    export = client.get(f"/api/surveys/{survey['id']}/answers.csv", headers=ADMIN).text
    assert export.count("\n") == 1  # the header only
    counts = state(client, survey["id"])
    assert (counts["declines"], counts["joined"], counts["completed"]) == (1, 0, 0)
    agreed = page.post(
        f"/q/{link['slug']}", data={"csrf_token": csrf, "decision": "agree", "PROLIFIC_PID": "y"}
    )
    assert agreed.status_code == 303 and agreed.headers["location"] == "/survey"
    assert [r["external_id"] for r in respondents(client, survey["id"])] == ["y"]
    assert page.post(f"/q/{link['slug']}", data={"decision": "agree"}).status_code == 403


def test_completion_code_and_redirect_after_the_last_answer(client, survey) -> None:
    done_url = "https://app.prolific.com/submissions/complete?cc=C0MPL3TE"
    link = configure(client, survey["id"], completion_code="C0MPL3TE", redirect_url=done_url)
    person = joined(client, *visit(client, link, "?PROLIFIC_PID=fin"))
    me = client.get("/api/surveys/me", headers=person.headers).json()
    assert (me["completion_code"], me["redirect_url"]) == (None, None)  # not before the end
    answer_all(person)
    me = client.get("/api/surveys/me", headers=person.headers).json()
    assert me["finished"] and (me["completion_code"], me["redirect_url"]) == ("C0MPL3TE", done_url)
    [invited] = invite(client, survey["id"])
    answer_all(invited)
    assert client.get("/api/surveys/me", headers=invited.headers).json()["completion_code"] is None
    assert state(client, survey["id"])["completed"] == 1


def test_returning_browser_without_ids_keeps_its_respondent(client, survey) -> None:
    link = configure(client, survey["id"])
    page, _ = visit(client, link)
    token = page.cookies[RESPONDENT_COOKIE]
    assert page.get(f"/q/{link['slug']}").status_code == 303
    assert page.cookies[RESPONDENT_COOKIE] == token
    assert len(respondents(client, survey["id"])) == 1


def test_closed_unknown_and_overlong_links(client, survey) -> None:
    link = configure(client, survey["id"], enabled=False)
    assert visit(client, link)[1].status_code == 410
    assert browser(client).get("/q/no-such-link").status_code == 404
    assert browser(client).get("/q/" + "x" * 100).status_code == 404
    configure(client, survey["id"])
    response = visit(client, link, "?PROLIFIC_PID=" + "x" * 201)[1]
    assert response.status_code == 422 and "PROLIFIC_PID" in response.text


def test_joins_are_rate_limited_per_client(client, survey) -> None:
    link = configure(client, survey["id"])
    client.app.state.join_limiter = LoginLimiter(2)
    assert [visit(client, link)[1].status_code for _ in range(3)] == [303, 303, 429]


def test_survey_page_form_sets_the_open_link(client, survey) -> None:
    page = logged_in(client)
    path = f"/surveys/{survey['id']}"
    assert "No open link yet" in page.get(path).text
    form = {
        "csrf_token": csrf_token(page, path),
        "enabled": "on",
        "max_participants": "4",
        "external_params": "PROLIFIC_PID, STUDY_ID",
        "completion_code": "CODE1",
        "redirect_url": "",
        "consent_text": "",
    }
    saved = page.post(f"{path}/crowd", data=form)
    assert saved.status_code == 303 and saved.headers["location"] == f"{path}#crowd"
    link = state(client, survey["id"])
    assert (link["max_participants"], link["external_params"]) == (4, ["PROLIFIC_PID", "STUDY_ID"])
    assert (link["redirect_url"], link["consent_text"]) == (None, None)
    html = page.get(path).text
    assert f"http://testserver/q/{link['slug']}" in html and "0 of 4 joined" in html
    assert audit(html) == []
    typed = {"redirect_url": "ftp://x.org/", "consent_text": "Kept as typed"}
    bad = page.post(f"{path}/crowd", data=form | typed)
    assert bad.status_code == 422 and "Not saved: redirect_url" in bad.text
    assert "Kept as typed</textarea>" in bad.text and 'value="ftp://x.org/"' in bad.text
    assert 'value="PROLIFIC_PID, STUDY_ID"' in bad.text and audit(bad.text) == []
    assert page.post(f"{path}/crowd", data=form | {"max_participants": "-1"}).status_code == 422
    stranger = browser(client).post(f"{path}/crowd", data=form | {"completion_code": "HACK"})
    assert stranger.status_code in (303, 403)
    assert state(client, survey["id"])["completion_code"] == "CODE1"
