"""A study's open link through the API: configure it, visit it with a cookie jar of one's
own, and the participant a visit made."""

from __future__ import annotations

import html
import re
from typing import Any

import httpx
from fastapi.testclient import TestClient
from playwright.sync_api import Browser, expect

from app.core.auth import PARTICIPANT_COOKIE
from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN as SERVER_ADMIN_TOKEN
from tests.support.browser import new_page
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.studies import Player
from tests.support.web import ADMIN

SETTINGS = {"enabled": True, "max_participants": 50}
HIDDEN_RE = re.compile(r'<input type="hidden" name="([^"]+)" value="([^"]*)">')


def configure(client: TestClient, study_id: int, **options: Any) -> dict[str, Any]:
    response = client.put(f"/api/studies/{study_id}/crowd", json=SETTINGS | options, headers=ADMIN)
    assert response.status_code == 200, response.text
    return response.json()


def visitor(client: TestClient) -> TestClient:
    """A browser of its own (an empty cookie jar) on the same app."""
    return TestClient(client.app, follow_redirects=False)


def visit(client: TestClient, link: dict[str, Any], query: str = "") -> tuple[TestClient, Any]:
    """Open the study's link in a new browser and press Start where the page offers it (a
    link without consent text); the answer is the last response (the join's redirect, or a
    consent, full or closed page)."""
    browser = visitor(client)
    return browser, join(browser, f"/s/{link['slug']}{query}")


def join(
    browser: httpx.Client,
    url: str,
    params: dict[str, str] | None = None,
    headers: dict[str, str] | None = None,
) -> httpx.Response:
    """``GET url`` (an open link, any kind) and press Start where the page offers it; the
    ``headers`` go with both requests."""
    return start(browser, browser.get(url, params=params, headers=headers), headers)


def start(
    browser: httpx.Client, page: httpx.Response, headers: dict[str, str] | None = None
) -> httpx.Response:
    """Press the open-link page's Start button if it has one (its form's hidden fields sent
    back, as a browser does); otherwise ``page`` itself."""
    if page.status_code != 200 or 'id="start"' not in page.text:
        return page
    fields = {n: html.unescape(v) for n, v in HIDDEN_RE.findall(page.text)}
    fields["decision"] = "agree"
    return browser.post(page.url.path, data=fields, headers=headers)


def joined_player(client: TestClient, browser: TestClient, response: Any) -> Player:
    assert response.status_code == 303, response.text
    token = browser.cookies[PARTICIPANT_COOKIE]
    me = client.get("/api/participants/me", headers={"Authorization": f"Bearer {token}"})
    return Player(client, me.json()["id"], token, "")


# --- the open link in a browser (the browser tests' ``server``) -----------------------------

_SERVER_ADMIN = {"Authorization": f"Bearer {SERVER_ADMIN_TOKEN}"}
_DESKTOP = {"width": 1280, "height": 900}


def turned_away(browser: Browser, errors: list[str], link: str, settings_url: str) -> None:
    """pw-1's id in another browser gets "already taken part"; once the researcher closes
    the link (``settings_url``), a new visitor gets "closed": both pages pass axe."""
    _, taken = new_page(browser, errors, viewport=_DESKTOP)
    taken.goto(f"{link}?PROLIFIC_PID=pw-1&STUDY_ID=st&SESSION_ID=another")
    expect(taken.locator("h1")).to_have_text("This id has already taken part")
    assert_accessible(taken, "already taken part page")
    with httpx.Client(headers=_SERVER_ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        closed = {"enabled": False, "max_participants": 5}
        assert api.put(settings_url, json=closed).status_code == 200
    _, new = new_page(browser, errors, viewport=_DESKTOP)
    new.goto(f"{link}?PROLIFIC_PID=pw-5")
    expect(new.locator("h1")).to_have_text("This link is closed")
    expect(new.locator("p.error")).to_contain_text("not taking new people")
    assert_accessible(new, "closed link page")
    refusals = [e for e in errors if "status of 409" in e or "status of 410" in e]
    assert len(refusals) == 2  # Chromium logs the two refusals' statuses; nothing else
    errors[:] = [e for e in errors if e not in refusals]
