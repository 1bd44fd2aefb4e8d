"""Clips in an ordinary study in a real browser (issue 41 §3), on a desktop and on a phone: the
bracket page plays both candidates' clips, pausing one swaps it for its still, the arrow key
labels as ever and the label records the clip; with reduced motion the stills show, each
with a Play control that starts its clip. axe-core audits every state."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    ADMIN_TOKEN,
    DESKTOP,
    PHONE,
    fits_width,
    new_page,
    wait_for_match,
)
from tests.support.labelling import wait_until_prepared
from tests.support.wait import wait_for

pytestmark = pytest.mark.browser
CLIP = re.compile(r"/clip$")


@pytest.fixture(scope="module")
def study(api: httpx.Client) -> dict[str, Any]:
    body = {"name": "Clips study", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 6}
    created = api.post("/api/studies", json=body | {"clips": True})
    assert created.status_code == 201, created.text
    wait_until_prepared(api, created.json()["id"])
    return wait_for(
        lambda: api.get(f"/api/studies/{created.json()['id']}").json(),
        lambda s: s["clips_ready"] or s["error"],
        what="the study's clips",
        timeout_s=300,
        every_s=0.5,
    )


def audited(page: Page, what: str) -> None:
    assert fits_width(page), f"{what}: wider than the window"
    assert_accessible(page, what)


def open_bracket(browser: Browser, api: httpx.Client, study: dict[str, Any], base: str, **kw):
    invited = api.post(f"/api/studies/{study['id']}/participants").json()
    errors: list[str] = []
    context, page = new_page(browser, errors, **kw)
    page.goto(invited["invite_url"])
    page.wait_for_url(f"{base}/participate")
    page.click("#start")
    page.wait_for_url(f"{base}/participate/label")
    return context, page, invited, errors


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_bracket_plays_clips_pauses_to_stills_and_records_them(
    server, browser: Browser, api: httpx.Client, study, viewport
) -> None:
    assert study["clips_ready"], study
    base, _ = server
    where = "on a phone" if viewport == PHONE else "on a desktop"
    context, page, invited, errors = open_bracket(browser, api, study, base, viewport=viewport)
    first = wait_for_match(page)
    for side, word in (("a", "left"), ("b", "right")):
        expect(page.locator(f"#img-{side}")).to_have_attribute("src", CLIP)
        expect(page.locator(f"#motion-{side}")).to_have_text(f"Pause the {word} candidate")
    audited(page, f"a match with clips playing {where}")

    page.click("#motion-a")  # pausing swaps the clip for its still
    still = page.get_attribute("#img-a", "data-still")
    assert still and still.endswith("/image")
    expect(page.locator("#img-a")).to_have_attribute("src", still)
    expect(page.locator("#motion-a")).to_have_text("Play the left candidate")
    expect(page.locator("#img-b")).to_have_attribute("src", CLIP)
    audited(page, f"a match with the left clip paused {where}")

    page.keyboard.press("ArrowRight")  # the labelling keys as ever
    wait_for_match(page, first)
    labels = api.get(f"/api/studies/{study['id']}/export/labels.jsonl").text
    assert f'"participant_id": {invited["id"]}' in labels
    mine = [line for line in labels.splitlines() if f'"participant_id": {invited["id"]},' in line]
    assert len(mine) == 1 and '"stimulus": "clip"' in mine[0]
    context.close()

    # Reduced motion: the stills, each with a Play control that starts its clip.
    context, calm, _, calm_errors = open_bracket(
        browser, api, study, base, viewport=viewport, reduced_motion="reduce"
    )
    wait_for_match(calm)
    expect(calm.locator("#img-a")).to_have_attribute("src", re.compile(r"/image$"))
    expect(calm.locator("#motion-a")).to_have_text("Play the left candidate")
    audited(calm, f"a match with reduced motion {where}")
    calm.click("#motion-a")
    expect(calm.locator("#img-a")).to_have_attribute("src", CLIP)
    expect(calm.locator("#motion-a")).to_have_text("Pause the left candidate")
    context.close()
    assert errors == [] and calm_errors == []


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_study_page_says_its_clips_are_ready(server, browser: Browser, study, viewport) -> None:
    base, _ = server
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study['id']}")
    expect(page.locator("#clips-state")).to_have_text("clips ready")
    audited(page, "the study page of a study whose clips are ready")
    context.close()
    assert errors == []
