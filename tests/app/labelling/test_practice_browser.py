"""A real browser through practice (issue 28 §3): the instructions lead to two practice pairs
(one instructed, one without a right answer), each answered by a click and followed by its
feedback, then to the bracket; nothing of practice is stored. On a desktop and on a phone,
axe-core audits every state a participant reaches: the instructions, a pair shown, the
feedback (after a reload too)."""

from __future__ import annotations

import re
from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    DESKTOP,
    PHONE,
    new_page,
    wait_for_match,
    wait_until_still,
)
from tests.support.labelling import wait_until_prepared

pytestmark = pytest.mark.browser
PAIRS = 2
FEEDBACK = re.compile(r"^(Right|Not quite): the marker was on the (left|right)\.$")


@pytest.fixture(scope="module")
def study(api: httpx.Client) -> dict[str, Any]:
    body = {"name": "Practice study", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 2}
    created = api.post("/api/studies", json=body | {"practice_pairs": PAIRS})
    assert created.status_code == 201, created.text
    return wait_until_prepared(api, created.json()["id"])


def _practise(page: Page, base: str, what: str) -> list[str]:
    """Answer every practice pair (the left picture), auditing each state; the feedback."""
    said = []
    for position in range(PAIRS):
        expect(page.locator("#practice-count")).to_have_text(
            f"Practice pair {position + 1} of {PAIRS}."
        )
        expect(page.locator("#practice-left img")).to_have_js_property("complete", True)
        wait_until_still(page)
        assert_accessible(page, f"practice pair {position + 1} on a {what}")
        page.click("#practice-left")
        feedback = page.locator("#feedback")
        expect(feedback).to_be_visible()
        said.append(feedback.inner_text().strip())
        page.reload()  # the same feedback again: nothing breaks, nothing is stored
        expect(feedback).to_have_text(said[-1])
        wait_until_still(page)
        assert_accessible(page, f"feedback on practice pair {position + 1} on a {what}")
        page.click("#next")
    page.wait_for_url(f"{base}/participate/label")
    return said


@pytest.mark.parametrize(
    ("viewport", "device"),
    [(DESKTOP, {}), (PHONE, {"is_mobile": True, "has_touch": True})],
    ids=["desktop", "phone"],
)
def test_practice_then_the_bracket(
    server, browser: Browser, api: httpx.Client, study, viewport, device
) -> None:
    base, _ = server
    invited = api.post(f"/api/studies/{study['id']}/participants").json()
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport, **device)
    what = "phone" if device else "desktop"
    page.goto(invited["invite_url"])
    page.wait_for_url(f"{base}/participate")
    expect(page.locator("#practice-note")).to_contain_text(f"{PAIRS} practice pairs")
    assert_accessible(page, f"instructions with practice on a {what}")
    page.click("#start")
    page.wait_for_url(f"{base}/participate/practice")
    said = _practise(page, base, what)
    assert sum(bool(FEEDBACK.match(s)) for s in said) == 1  # the instructed pair's
    assert sum("no right answer" in s for s in said) == 1
    wait_for_match(page)  # the bracket's first match is shown

    me = {"Authorization": f"Bearer {invited['token']}"}
    assert api.get("/api/participants/me", headers=me).json()["progress"]["done"] == 0
    labels = api.get(f"/api/studies/{study['id']}/labels.csv").text
    assert len(labels.strip().splitlines()) == 1  # the header: no test here labels a match
    assert api.get("/api/participants/me/practice", headers=me).json() != []
    context.close()
    assert errors == []
