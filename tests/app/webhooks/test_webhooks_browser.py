"""A real browser through the "Webhooks" section of the study and survey pages (issue 29
§3): the researcher registers a URL (a refused one first: the page comes back with it as typed
and the rule it breaks),
sees its secret, an event's delivery in the attempts log, and removes it. axe-core audits
both pages with a webhook and its log, on a desktop and on a phone. The receiver listens on
127.0.0.1 (the browser tests' server allows loopback targets only)."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    DESKTOP,
    PHONE,
    researcher_page,
    wait_until_still,
)
from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.surveys import paper_body, two_finished_participants
from tests.support.wait import wait_for
from tests.support.webhooks import Receiver, events

pytestmark = pytest.mark.browser


def _register(page: Page, path: str, url: str) -> None:
    page.goto(f"{path}#webhooks")
    page.fill("#webhook-url", url)
    page.click("#webhook-form button[type=submit]")


def _audit_both_sizes(page: Page, what: str) -> None:
    wait_until_still(page)
    assert_accessible(page, f"{what} on a desktop")
    page.set_viewport_size(PHONE)
    wait_until_still(page)
    assert_accessible(page, f"{what} on a phone")
    page.set_viewport_size(DESKTOP)


def _remove(page: Page, path: str) -> None:
    page.locator(".webhook button", has_text="Remove").click()
    page.wait_for_url(f"{path}#webhooks")
    expect(page.locator("#no-webhooks")).to_be_visible()


def test_the_study_page_registers_a_webhook_and_shows_its_log(
    server, browser: Browser, api: httpx.Client, screens: Path
) -> None:
    base, _ = server
    created = api.post(
        "/api/studies", json={"name": "Hooks", "env_id": "Hopper-v5", "n_candidates": 4}
    )
    sid = wait_until_prepared(api, created.json()["id"])["id"]
    path, errors = f"{base}/studies/{sid}", []
    page = researcher_page(browser, base, errors)
    _register(page, path, "https://10.0.0.1/hook")
    expect(page.locator("#webhook-error")).to_contain_text("10.0.0.1 is a private address")
    expect(page.locator("#webhook-url")).to_have_value("https://10.0.0.1/hook")  # as typed
    _audit_both_sizes(page, "the study page with the refused webhook")
    assert [e for e in errors if "422" not in e] == []  # the browser logs the refusal's 422
    errors.clear()
    with Receiver() as receiver:
        _register(page, path, receiver.url())
        page.wait_for_url(f"{path}#webhooks")
        expect(page.locator(".webhook-url")).to_have_text(receiver.url())
        expect(page.locator(".webhook-secret")).to_have_value(receiver_secret(api, sid))
        token = api.post(f"/api/studies/{sid}/participants").json()["token"]
        label_bracket(api, token, lambda match: match["a"]["candidate_id"])
        [hook] = api.get("/api/webhooks", params={"study_id": sid}).json()
        wait_for(
            lambda: events(api, hook["id"], headers=admin(api)),
            lambda evs: evs and all(e["status"] == "delivered" for e in evs),
            what="the study's events delivered",
        )
        assert receiver.received()
        page.reload()
        expect(page.locator(".webhook-attempts").first).to_contain_text("HTTP 200")
    expect(page.locator(".webhook-counts")).to_contain_text("delivered")
    page.locator("#webhooks + .webhooks").screenshot(path=screens / "webhooks-study.png")
    _audit_both_sizes(page, "study page with a webhook and its attempts")
    _remove(page, path)
    assert errors == []


def admin(api: httpx.Client) -> dict[str, str]:
    return {"Authorization": api.headers["Authorization"]}


def receiver_secret(api: httpx.Client, study_id: int) -> str:
    [hook] = api.get("/api/webhooks", params={"study_id": study_id}).json()
    return hook["secret"]


def test_the_survey_page_registers_and_removes_a_webhook(
    server, browser: Browser, api: httpx.Client
) -> None:
    base, _ = server
    sid = two_finished_participants(base)
    people = [p["id"] for p in api.get(f"/api/studies/{sid}/participants").json()]
    trees = [{"kind": "participant", "participant_id": p} for p in people[:2]]
    survey = api.post("/api/surveys", json=paper_body(*trees)).json()
    path, errors = f"{base}/surveys/{survey['id']}", []
    page = researcher_page(browser, base, errors)
    with Receiver() as receiver:
        _register(page, path, receiver.url())
        page.wait_for_url(f"{path}#webhooks")
        expect(page.locator(".webhook-url")).to_have_text(receiver.url())
        expect(page.locator("#webhooks + .webhooks")).to_contain_text("respondent.finished")
        _audit_both_sizes(page, "survey page with a webhook")
    _remove(page, path)
    assert errors == []
