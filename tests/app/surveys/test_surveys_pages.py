"""The survey pages without a browser: who may see them, the invite link's cookie, the
security rules every page follows (CSP, no inline code, no admin token), and what the survey
page shows."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.http.access_log import mask_invite_tokens
from app.surveys.respond import RESPONDENT_COOKIE
from tests.support.surveys import finished, invite, paper_answers, paper_body
from tests.support.web import ADMIN, ADMIN_TOKEN, audit, browser, logged_in


@pytest.fixture(scope="module")
def survey(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    one = {"kind": "participant", "participant_id": finished(client, study["id"], "a")}
    two = {"kind": "participant", "participant_id": finished(client, study["id"], "b")}
    response = client.post("/api/surveys", json=paper_body(one, two), headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()


def test_researcher_pages_send_strangers_to_login(client, survey) -> None:
    stranger = browser(client)
    for path in ("/surveys", "/surveys/new", f"/surveys/{survey['id']}"):
        response = stranger.get(path)
        assert response.status_code == 303 and response.headers["location"].startswith(
            "/login?next=/surveys"
        ), path


def test_invite_link_sets_the_cookie_and_resumes(client, survey) -> None:
    [person] = invite(client, survey["id"])
    phone = browser(client)
    assert phone.get("/survey").status_code == 401  # no invitation in this browser yet
    response = phone.get(f"/r/{person.token}")
    assert response.status_code == 303 and response.headers["location"] == "/survey"
    cookie = response.headers["set-cookie"]
    assert f"{RESPONDENT_COOKIE}={person.token}" in cookie
    assert "HttpOnly" in cookie and "SameSite=lax" in cookie
    page = phone.get("/survey")
    assert page.status_code == 200 and 'data-started="false"' in page.text
    screen = person.screen()
    assert person.answer(screen["position"], paper_answers(screen, q1="same")).status_code == 201
    assert 'data-started="true"' in phone.get("/survey").text
    # The page's script answers with the cookie, and must send the AJAX header to do so.
    url = "/api/surveys/me/screens/2/answers"
    body = {"answers": {}, "screen_ms": 5}
    assert phone.post(url, json=body).status_code == 403
    assert phone.post(url, json=body, headers={"X-Requested-With": "acv"}).status_code == 422
    assert browser(client).get("/r/not-a-real-token").status_code == 404


def test_pages_follow_the_security_rules(client, survey) -> None:
    [person] = invite(client, survey["id"])
    page = logged_in(client)
    respondent = browser(client)
    respondent.get(f"/r/{person.token}")
    pages = [
        page.get(p)
        for p in ("/surveys", "/surveys/new", f"/surveys/{survey['id']}", "/surveys/999999")
    ]
    pages.append(respondent.get("/survey"))
    assert [r.status_code for r in pages] == [200, 200, 200, 404, 200]
    for response in pages:
        assert "script-src 'self'" in response.headers["content-security-policy"]
        assert response.headers["referrer-policy"] == "no-referrer"
        assert ADMIN_TOKEN not in response.text
        assert audit(response.text) == [], response.url
    assert person.token not in pages[-1].text  # the respondent's page never shows the token


def test_survey_page_shows_rule_respondents_and_paper(client, survey) -> None:
    invite(client, survey["id"], count=2)
    html = logged_in(client).get(f"/surveys/{survey['id']}").text
    assert "exclude respondents who fail the attention check" in html
    assert html.count("http://testserver/r/") >= 2
    assert "20/20 (100%)" in html and "17/20 (85%)" in html and "0.62–0.97" in html
    assert "answers.csv" in html and "answers.jsonl" in html


def test_new_survey_page_offers_the_menus(client, survey) -> None:
    detail = client.get(f"/api/surveys/{survey['id']}", headers=ADMIN).json()
    pid = detail["stimuli"][0]["trees"][0]["source"]["participant_id"]
    html = logged_in(client).get("/surveys/new").text
    assert f'<option value="{pid}">participant {pid}' in html
    assert "Agent Preference Tree" in html and 'type="file"' in html


def test_survey_invite_tokens_stay_out_of_the_access_log() -> None:
    assert mask_invite_tokens("/r/AbC-123_x") == "/r/***"
    assert mask_invite_tokens("/p/AbC-123_x") == "/p/***"
    assert mask_invite_tokens("/surveys/3") == "/surveys/3"
    assert mask_invite_tokens("/q/slug?PROLIFIC_PID=abc") == "/q/***"
