"""A real browser through a crowd study (issue 14): the researcher opens the study's link
with the study page's form; a visitor arrives with Prolific's query parameters, consents,
plays the bracket (sides as the server placed them), answers the consistency check, sees
the completion code and is sent to the completion URL (a local page this test serves).
Another visitor declines; a third finds the study full. The study page then shows the
quality flags and the agreement heat map (screenshots: /tmp/acv_screens).
axe-core checks every page added or changed.
"""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, new_page, shown, wait_for_match
from tests.support.crowd import join, turned_away
from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S

pytestmark = pytest.mark.browser
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
DESKTOP = {"width": 1280, "height": 900}


def ready_study(api: httpx.Client) -> int:
    study = api.post(
        "/api/studies",
        json={"name": "Crowd study", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 8},
    ).json()
    wait_until_prepared(api, study["id"])
    return study["id"]


def open_the_link(page: Page, base: str, study_id: int, platform: str, errors: list[str]) -> str:
    """Fill the study page's crowd form (first with a bad field, refused); returns the open
    link it then shows."""
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study_id}")
    page.check("#crowd-enabled")
    page.fill("#max_participants", "2")
    page.fill("#consent_text", "We store your choices and your Prolific id, nothing else.")
    page.fill("#completion_code", "C0MPL3TE")
    page.fill("#redirect_url", f"{platform}/submissions/complete?cc=C0MPL3TE")
    page.check("#consistency_check")
    page.fill("#external_params", "PROLIFIC_PID, study-id")  # refused: shown again as typed
    page.click("text=Save open link")
    expect(page.locator("#crowd-error")).to_contain_text("Not saved: external_params")
    expect(page.locator("#consent_text")).to_have_value(
        "We store your choices and your Prolific id, nothing else."
    )
    assert_accessible(page, "study page, open-link form refused")
    refused = [e for e in errors if "status of 422" in e]
    assert len(refused) == 1  # Chromium logs the refusal's status; nothing else
    errors.remove(refused[0])
    page.fill("#external_params", "PROLIFIC_PID, STUDY_ID, SESSION_ID")
    page.click("text=Save open link")
    page.wait_for_url(f"{base}/studies/{study_id}#crowd")
    return page.inner_text("#open-link")


def play_in_browser(p: Page) -> None:
    """Decide the 3 matches: left, right, left (by click and keys)."""
    match = wait_for_match(p)
    for how in ("#pick-a", "ArrowRight", "ArrowLeft"):
        if how.startswith("Arrow"):
            p.keyboard.press(how)
        else:
            p.click(how)
        if how != "ArrowLeft":
            match = wait_for_match(p, match)


def test_open_link_consent_bracket_check_and_completion(
    server, browser: Browser, screens, platform: str
) -> None:
    base, _ = server
    errors: list[str] = []
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study_id = ready_study(api)
    _, page = new_page(browser, errors, viewport=DESKTOP)
    link = open_the_link(page, base, study_id, platform, errors)
    assert link.startswith(f"{base}/s/")
    assert_accessible(page, "study page with the crowd form")

    _, p = new_page(browser, errors, viewport=DESKTOP)
    p.goto(f"{link}?PROLIFIC_PID=pw-1&STUDY_ID=st&SESSION_ID=se")
    expect(p.locator("#consent-text")).to_contain_text("Prolific id")
    assert_accessible(p, "consent page")
    p.click("#agree")
    p.wait_for_url(f"{base}/participate")
    p.click("#start")
    wait_for_match(p)
    assert_accessible(p, "labelling page")
    placed = (shown(p, "a"), shown(p, "b"))
    play_in_browser(p)
    p.wait_for_url(f"{base}/participate/check")
    assert_accessible(p, "consistency check page")
    check = (
        int(p.get_attribute("#check-left", "value")),
        int(p.get_attribute("#check-right", "value")),
    )
    stale = p.context.new_page()  # a second tab on the same check, answered after the first
    stale.goto(f"{base}/participate/check")
    p.click("#check-left")
    p.wait_for_url(f"{base}/participate/thanks")
    stale.click("#check-right")
    expect(stale.locator("h1")).to_have_text("Not stored")
    expect(stale.locator("#message-text")).to_contain_text("your first answer is kept")
    assert_accessible(stale, "a second tab's check answer, not stored")
    stale.click("#continue")
    stale.wait_for_url(f"{base}/participate/thanks")
    stale.close()
    expect(p.locator("#completion-code")).to_have_text("C0MPL3TE")
    expect(p.locator("#stay-here")).to_be_visible()  # the way back waits, and can be stopped
    assert_accessible(p, "thank-you page with the completion code")
    p.click("#stay-here")
    expect(p.locator("#complete-link")).to_be_focused()
    expect(p.locator("#redirect-note")).to_contain_text("you stay here")
    p.click("#complete-link")
    p.wait_for_url(f"{platform}/submissions/complete?cc=C0MPL3TE")
    expect(p.locator("h1")).to_have_text("Submission complete")

    _, d = new_page(browser, errors, viewport=DESKTOP)
    d.goto(f"{link}?PROLIFIC_PID=pw-2")
    d.click("#decline")
    expect(d.locator("h1")).to_have_text("You declined")
    assert_accessible(d, "declined page")

    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:  # now one place
        assert (
            api.put(
                f"/api/studies/{study_id}/crowd", json={"enabled": True, "max_participants": 1}
            ).status_code
            == 200
        )
    _, f = new_page(browser, errors, viewport=DESKTOP)
    f.goto(f"{link}?PROLIFIC_PID=pw-4")
    expect(f.locator("h1")).to_have_text("This study is full")
    assert_accessible(f, "study full page")

    turned_away(browser, errors, link, f"{base}/api/studies/{study_id}/crowd")

    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        rows = api.get(f"/api/studies/{study_id}/export/labels.jsonl").text.splitlines()
        quality = api.get(f"/api/studies/{study_id}/quality").json()
        crowd = api.get(f"/api/studies/{study_id}/crowd").json()
    assert len(rows) == 3 and '"external_id": "pw-1"' in rows[0]
    assert '"side": "left"' in rows[0] and f'"left": {placed[0]}' in rows[0]
    person = quality["participants"][0]
    assert person["external_id"] == "pw-1" and person["consistency_agrees"] is not None
    assert (crowd["joined"], crowd["declines"]) == (1, 1)
    first_round = [json.loads(r) for r in rows if '"round": 1' in r]
    assert check in [(r["right"], r["left"]) for r in first_round]  # sides swapped
    assert errors == []


def _play_api(base: str, link: str, pid: str, pick) -> None:
    """Join by the open link as ``pid`` and decide every match with ``pick``."""
    with httpx.Client(base_url=base, timeout=HTTP_TIMEOUT_S, follow_redirects=False) as visitor:
        token = join(visitor, f"{link}?PROLIFIC_PID={pid}").cookies["acv_participant"]
        label_bracket(visitor, token, pick, response_ms=300 * len(pid))


def test_study_page_shows_agreement_and_quality_flags(
    server, browser: Browser, screens: Path
) -> None:
    base, _ = server
    errors: list[str] = []
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study_id = api.post(
            "/api/studies",
            json={"name": "Crowd agreement", "env_id": "Hopper-v5", "n_candidates": 8, "seed": 2},
        ).json()["id"]
        wait_until_prepared(api, study_id)
        link = api.put(
            f"/api/studies/{study_id}/crowd", json={"enabled": True, "max_participants": 10}
        ).json()["url"]
    low = lambda m: min(m["a"]["candidate_id"], m["b"]["candidate_id"])  # noqa: E731
    high = lambda m: max(m["a"]["candidate_id"], m["b"]["candidate_id"])  # noqa: E731
    for pid, pick in (("p", lambda m: m["left"]), ("low1", low), ("low22", low), ("hi333", high)):
        _play_api(base, link, pid, pick)
    _, page = new_page(browser, errors, viewport={"width": 1280, "height": 1000})
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study_id}#quality")
    expect(page.locator("#heat-map tbody tr")).to_have_count(4)
    expect(page.locator("#quality-table tbody tr").first.locator(".flag")).to_have_text(
        ["position bias", "fast"]
    )
    expect(page.locator("#agreement-summary")).to_contain_text("Krippendorff")
    expect(page.locator("#quality-table .reliability")).to_have_text(["0.25 (0 checks)"] * 4)
    assert_accessible(page, "study page with agreement and flags")
    page.set_viewport_size({"width": 390, "height": 844})  # a phone: the tables scroll inside
    page.goto(f"{base}/studies/{study_id}#quality")
    expect(page.locator("#quality-table .reliability")).to_have_count(4)
    assert page.evaluate("document.documentElement.scrollWidth") <= 390
    assert_accessible(page, "study page with agreement and flags, on a phone")
    page.set_viewport_size({"width": 1280, "height": 1000})
    page.goto(f"{base}/studies/{study_id}#quality")
    expect(page.locator("#heat-map tbody tr")).to_have_count(4)
    page.screenshot(path=screens / "study-full.png", full_page=True)
    top = page.locator("#quality").bounding_box()["y"] + page.evaluate("window.scrollY")
    bottom = page.locator("#trees").bounding_box()["y"] + page.evaluate("window.scrollY")
    page.screenshot(
        path=screens / "study.png",
        full_page=True,
        clip={"x": 0, "y": top - 8, "width": 1280, "height": bottom - top},
    )
    assert errors == []
