"""The HTML pages without a browser: access, login, CSRF, forms, invite links, downloads and
the security rules every page follows (no inline scripts, a CSP, no admin token).

Runs on PostgreSQL (the ``client`` fixture); each test drives its own cookie jar.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from collections.abc import Callable
from typing import Any

import pytest
from fastapi.testclient import TestClient

from engine.treefile import tree_from_json
from tests.support.studies import Player, wait_ready
from tests.support.web import ADMIN, ADMIN_TOKEN, audit, browser, csrf_token, logged_in

# postgres_only: pages are the subject, not storage.
pytestmark = pytest.mark.postgres_only


@pytest.mark.parametrize(
    "path",
    [
        "/studies",
        "/studies/new",
        "/studies/{id}",
        "/studies/{id}/trees.zip",
        "/studies/{id}/participants/1/tree.json",
    ],
)
def test_researcher_pages_send_strangers_to_login(
    client: TestClient, study: dict[str, Any], path: str
) -> None:
    path = path.format(id=study["id"])
    response = browser(client).get(path)
    assert response.status_code == 303
    assert response.headers["location"] == f"/login?next={path}"


def test_a_form_posted_after_the_login_lapsed_returns_to_its_page(
    client: TestClient, study: dict[str, Any]
) -> None:
    """After logging in again the researcher is back on the form's page, not on its target,
    which takes no ``GET``; a browser that opens such a target gets a page saying so."""
    target = f"/studies/{study['id']}/crowd"
    posted = browser(client).post(target, data={"enabled": "on"})
    assert posted.status_code == 303
    assert posted.headers["location"] == f"/login?next=/studies/{study['id']}"
    opened = logged_in(client).get(target, headers={"Accept": "text/html"})
    assert opened.status_code == 405 and "only takes a form" in opened.text
    assert opened.headers["allow"] == "POST" and audit(opened.text) == []


def test_login_sets_an_httponly_cookie_that_is_not_the_token(client: TestClient) -> None:
    page = browser(client)
    token = csrf_token(page, "/login")
    wrong = page.post("/login", data={"csrf_token": token, "token": "nope"})
    assert wrong.status_code == 401 and "not the admin token" in wrong.text
    response = page.post(
        "/login", data={"csrf_token": token, "token": ADMIN_TOKEN, "next": "//evil.example/x"}
    )
    assert response.status_code == 303 and response.headers["location"] == "/studies"
    cookie = response.headers["set-cookie"]
    assert "HttpOnly" in cookie and "samesite=lax" in cookie.lower()
    assert ADMIN_TOKEN not in cookie
    assert page.get("/studies").status_code == 200
    assert 'name="next" value="/studies/new"' in page.get("/login?next=/studies/new").text


@pytest.mark.parametrize("form", [{}, {"csrf_token": "forged"}])
def test_form_posts_without_a_valid_csrf_token_are_refused(
    client: TestClient, study: dict[str, Any], form: dict[str, str]
) -> None:
    page = logged_in(client)
    before = len(client.get(f"/api/studies/{study['id']}/participants", headers=ADMIN).json())
    response = page.post(f"/studies/{study['id']}/participants", data={**form, "count": "2"})
    assert response.status_code == 403 and "text/html" in response.headers["content-type"]
    after = len(client.get(f"/api/studies/{study['id']}/participants", headers=ADMIN).json())
    assert after == before
    assert browser(client).post("/login", data={**form, "token": ADMIN_TOKEN}).status_code == 403


@pytest.mark.parametrize(
    ("field", "value"),
    [("name", ""), ("n_candidates", "129"), ("p", "1.5"), ("seed", "-1"), ("p", "abc")],
)
def test_create_study_form_shows_errors_next_to_the_field(
    client: TestClient, field: str, value: str
) -> None:
    page = logged_in(client)
    form = {
        "csrf_token": csrf_token(page, "/studies/new"),
        "name": "Form study",
        "env_id": "Hopper-v5",
        "n_candidates": "4",
        "p": "0.9",
        "seed": "1",
        "sampling": "uniform",
        "instructions": "Pick one.",
    }
    response = page.post("/studies", data={**form, field: value})
    assert response.status_code == 422 and "text/html" in response.headers["content-type"]
    assert f'id="{field}-error"' in response.text
    assert f'value="{value}"' in response.text  # the form keeps what was typed


def test_create_study_form_and_invite_form(client: TestClient) -> None:
    page = logged_in(client)
    form = {
        "csrf_token": csrf_token(page, "/studies/new"),
        "name": "Form study",
        "env_id": "Hopper-v5",
        "n_candidates": "4",
        "p": "0.9",
        "seed": "1",
        "sampling": "uniform",
        "instructions": "Pick one.",
    }
    assert "unknown env" in page.post("/studies", data={**form, "env_id": "Nope-v0"}).text
    response = page.post("/studies", data=form)
    assert response.status_code == 303
    study_id = int(response.headers["location"].rsplit("/", 1)[1])
    assert wait_ready(client, study_id)["status"] == "ready"
    invited = page.post(
        f"/studies/{study_id}/participants", data={"csrf_token": form["csrf_token"], "count": "3"}
    )
    assert invited.headers["location"] == f"/studies/{study_id}?invited=3#participants"
    html = page.get(f"/studies/{study_id}").text
    links = re.findall(r'value="(http://testserver/p/[\w-]{43})"', html)
    assert len(links) == 3 and html.count("<figure>") == 4


def test_pages_follow_the_security_rules(
    client: TestClient, study: dict[str, Any], invite: Callable[..., Player]
) -> None:
    page = logged_in(client)
    person = invite()
    participant = browser(client)
    participant.get(f"/p/{person.token}")
    pages = [
        page.get(p)
        for p in (
            "/login",
            "/studies",
            "/studies/new",
            f"/studies/{study['id']}",
            "/studies/999999",
        )
    ]
    pages += [participant.get(p) for p in ("/participate", "/participate/label")]
    for response in pages:
        assert "script-src 'self'" in response.headers["content-security-policy"]
        assert response.headers["referrer-policy"] == "no-referrer"
        assert ADMIN_TOKEN not in response.text
        assert audit(response.text) == [], response.url


def test_invite_link_sets_the_cookie_and_resumes(
    client: TestClient, invite: Callable[..., Player]
) -> None:
    person = invite()
    page = browser(client)
    lost = page.get("/participate")  # no invitation in this browser yet: the way back, for
    assert lost.status_code == 401 and "on your study platform" in lost.text  # open links too
    first = page.get(f"/p/{person.token}")
    assert first.headers["location"] == "/participate"
    assert "HttpOnly" in first.headers["set-cookie"]
    assert page.get("/participate/thanks").headers["location"] == "/participate/label"
    match = person.next_match()
    person.label(match["match_id"], match["a"]["candidate_id"])
    assert browser(client).get(f"/p/{person.token}").headers["location"] == "/participate/label"
    person.play()
    assert page.get("/participate/label").headers["location"] == "/participate/thanks"
    thanks = page.get("/participate/thanks")
    assert f'data-tree-url="/api/participants/{person.id}/tree"' in thanks.text
    assert '<span class="brand">ACV</span>' in thanks.text  # no link to the researchers' login
    assert browser(client).get("/p/not-a-token").status_code == 404


def test_downloads_are_acv_tree_files(
    client: TestClient,
    study: dict[str, Any],
    make_study: Callable[..., dict[str, Any]],
    invite: Callable[..., Player],
) -> None:
    page = logged_in(client)
    done, open_ = invite(), invite()
    done.play()
    base = f"/studies/{study['id']}/participants"
    response = page.get(f"{base}/{done.id}/tree.json")
    assert response.status_code == 200
    assert "attachment" in response.headers["content-disposition"]
    assert tree_from_json(response.json()).judge == f"participant:{done.id}"
    assert page.get(f"{base}/{open_.id}/tree.json").status_code == 409
    other = make_study(seed=11)
    assert page.get(f"/studies/{other['id']}/participants/{done.id}/tree.json").status_code == 404
    archive = zipfile.ZipFile(io.BytesIO(page.get(f"/studies/{study['id']}/trees.zip").content))
    names = archive.namelist()
    assert f"study-{study['id']}-participant-{done.id}.acv-tree.json" in names
    assert all(tree_from_json(json.loads(archive.read(n))) for n in names)
