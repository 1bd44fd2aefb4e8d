"""Who an open link lets in (issue 24), for studies (``/s/``) and surveys (``/q/``) alike, on
SQLite and PostgreSQL:

- F4: an external id alone never hands over a session (only the browser that joined, or
  the same per-attempt ids, resume it); ids that are not printable UTF-8 are refused;
- F5: only people who came through the open link get its completion code and redirect;
- a closed link turns new people away with a clear page, and lets those who joined finish.
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

import pytest
from fastapi.testclient import TestClient

from app.core.auth import PARTICIPANT_COOKIE
from app.http.ratelimit import LoginLimiter
from app.surveys.respond import RESPONDENT_COOKIE
from tests.support.crowd import join, start
from tests.support.studies import Player
from tests.support.surveys import paper_body, participant_trees
from tests.support.web import ADMIN, browser, csrf_token

FIRST = "?PROLIFIC_PID=p-{n}&STUDY_ID=st&SESSION_ID=attempt-1"
COOKIES = {"s": PARTICIPANT_COOKIE, "q": RESPONDENT_COOKIE}
DONE = {"completion_code": "C0DE", "redirect_url": "https://example.org/done?cc=C0DE"}


@pytest.fixture(autouse=True)
def fresh_join_limit(client: TestClient) -> None:
    """Each test starts with no joins counted against the test client's address."""
    client.app.state.join_limiter = LoginLimiter(100)


@pytest.fixture(scope="module")
def owners(client: TestClient, study: dict[str, Any]) -> dict[str, str]:
    """The crowd-settings path of a study and of a survey, by link kind (``s``, ``q``)."""
    made = client.post(
        "/api/surveys", json=paper_body(*participant_trees(client, study["id"])), headers=ADMIN
    )
    assert made.status_code == 201, made.text
    return {
        "s": f"/api/studies/{study['id']}/crowd",
        "q": f"/api/surveys/{made.json()['id']}/crowd",
    }


def open_link(client: TestClient, path: str, **options: Any) -> str:
    """Set the open link's options; its path (``/s/<slug>`` or ``/q/<slug>``)."""
    body = {"enabled": True, "max_participants": 500} | options
    response = client.put(path, json=body, headers=ADMIN)
    assert response.status_code == 200, response.text
    return urlsplit(response.json()["url"]).path


@pytest.fixture(params=["s", "q"])
def kind(request: pytest.FixtureRequest) -> str:
    return request.param


def test_an_external_id_alone_does_not_resume_someone_else(client, owners, kind) -> None:
    path = open_link(client, owners[kind])
    query = FIRST.format(n=f"takeover-{kind}")
    first = browser(client)
    assert join(first, path + query).status_code == 303
    theirs = first.cookies[COOKIES[kind]]

    for other in ("?PROLIFIC_PID=p-takeover-" + kind, query.replace("attempt-1", "attempt-9")):
        stranger = browser(client)
        page = stranger.get(path + other)
        assert page.status_code == 409, page.text
        assert "already taken part" in page.text and COOKIES[kind] not in stranger.cookies

    same_attempt = browser(client)  # the platform's own link again: same SESSION_ID
    assert same_attempt.get(path + query).status_code == 303
    assert same_attempt.cookies[COOKIES[kind]] == theirs
    again = first.get(path + "?PROLIFIC_PID=p-takeover-" + kind)  # their own browser
    assert again.status_code == 303 and first.cookies[COOKIES[kind]] == theirs


@pytest.mark.parametrize(
    "raw",
    [
        "%FF%FEid",  # not UTF-8
        "id%C3",  # a truncated UTF-8 sequence
        "id%7F",  # DEL
        "id%C2%85",  # U+0085 NEXT LINE (str.strip() would drop it)
        "id%E2%80%AE",  # U+202E RIGHT-TO-LEFT OVERRIDE
        "id%E2%80%A8",  # U+2028 LINE SEPARATOR
        "id%E2%80%A9",  # U+2029 PARAGRAPH SEPARATOR
        "id%E2%80%8B",  # U+200B ZERO WIDTH SPACE (format)
        "id%0A",  # a newline
    ],
)
def test_external_ids_must_be_printable_utf8(client, owners, kind, raw) -> None:
    path = open_link(client, owners[kind])
    response = browser(client).get(f"{path}?PROLIFIC_PID={raw}")
    assert response.status_code == 422, response.text
    assert "PROLIFIC_PID" in response.text and "printable" in response.text


def test_distinct_raw_ids_do_not_collide(client, owners, kind) -> None:
    """``%FF`` and ``%FE`` would both be stored as U+FFFD if decoded with replacement."""
    path = open_link(client, owners[kind])
    assert join(browser(client), f"{path}?PROLIFIC_PID=%C3%A9t%C3%A9-{kind}").status_code == 303
    assert browser(client).get(f"{path}?PROLIFIC_PID=%FFx-{kind}").status_code == 422


def test_invited_participants_get_no_completion_code(client, owners, study) -> None:
    open_link(client, owners["s"], **DONE)
    invited = client.post(f"/api/studies/{study['id']}/participants", headers=ADMIN).json()
    page = browser(client)
    assert page.get(urlsplit(invited["invite_url"]).path).status_code == 303
    Player(client, invited["id"], invited["token"], "").play()
    thanks = page.get("/participate/thanks")
    assert thanks.status_code == 200, thanks.text
    assert "C0DE" not in thanks.text and "complete-link" not in thanks.text

    crowd = browser(client)
    link = open_link(client, owners["s"], **DONE)
    assert join(crowd, link + "?PROLIFIC_PID=cc").status_code == 303
    token = crowd.cookies[PARTICIPANT_COOKIE]
    Player(client, 0, token, "").play()
    thanks = crowd.get("/participate/thanks")
    assert "C0DE" in thanks.text and "complete-link" in thanks.text


def test_a_closed_link_lets_those_in_finish_and_turns_new_people_away(client, owners, kind) -> None:
    path = open_link(client, owners[kind], consent_text="Agree to take part?")
    joined = browser(client)
    csrf = joined.get(path).text.split('name="csrf_token" value="')[1].split('"')[0]
    agreed = joined.post(path, data={"csrf_token": csrf, "decision": "agree"})
    assert agreed.status_code == 303
    open_link(client, owners[kind], enabled=False)

    resumed = joined.get(path)  # their cookie: on to where they were
    assert resumed.status_code == 303 and resumed.headers["location"] != path
    assert joined.get(resumed.headers["location"]).status_code in (200, 303)
    token = joined.cookies[COOKIES[kind]]
    me = "/api/participants/me/next-match" if kind == "s" else "/api/surveys/me/screen"
    assert client.get(me, headers={"Authorization": f"Bearer {token}"}).status_code == 200

    newcomer = browser(client)
    page = newcomer.get(path)
    assert page.status_code == 410 and "closed" in page.text
    assert "not taking new people" in page.text and COOKIES[kind] not in newcomer.cookies
    posted = newcomer.post(path, data={"csrf_token": csrf_token(newcomer), "decision": "agree"})
    assert posted.status_code == 410 and COOKIES[kind] not in newcomer.cookies


def test_fetching_the_link_takes_no_seat(client, owners, kind) -> None:
    """Link previewers and mail scanners ``GET`` (or ``HEAD``) a link they are sent: that
    shows the start page and makes no member; only pressing Start does."""
    path = open_link(client, owners[kind], consent_text=None, max_participants=500)
    joined = client.get(owners[kind], headers=ADMIN).json()["joined"]
    for n in range(3):
        page = browser(client).get(f"{path}?PROLIFIC_PID=scanner-{kind}-{n}")
        assert page.status_code == 200 and 'id="start"' in page.text
        assert 'id="decline"' not in page.text  # no consent text: nothing to decline
    head = browser(client).head(path)
    assert head.status_code == 200 and head.content == b""
    assert client.get(owners[kind], headers=ADMIN).json()["joined"] == joined

    person = browser(client)
    assert start(person, person.get(f"{path}?PROLIFIC_PID=scanner-{kind}-0")).status_code == 303
    assert COOKIES[kind] in person.cookies
    assert client.get(owners[kind], headers=ADMIN).json()["joined"] == joined + 1
