"""A real browser on the study page's live dashboard (issue 29 §1): the researcher opens the
page; participants label through the API, in another client; the dashboard shows their
progress without a reload (a marker set on the page's window survives), keeps answering
304s while nothing changes, pauses and resumes; axe-core finds no serious violation on a
desktop and on a phone (screenshot: /tmp/acv_screens/study-live.png)."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Locator, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    ADMIN_TOKEN,
    DESKTOP,
    PHONE,
    fits_width,
    new_page,
    wait_until_still,
)
from tests.support.labelling import wait_until_prepared

pytestmark = pytest.mark.browser
N = 4  # 3 matches per bracket

# The page's script counts the bodies it applied and the 304s it got (static/js/dashboard.js).
_MORE = "([what, than]) => Number(document.getElementById('dashboard').dataset[what]) > than"


def invite(api: httpx.Client, study_id: int) -> tuple[int, dict[str, str]]:
    """A new participant's id and credentials."""
    made = api.post(f"/api/studies/{study_id}/participants")
    assert made.status_code == 201, made.text
    return made.json()["id"], {"Authorization": f"Bearer {made.json()['token']}"}


def label(api: httpx.Client, me: dict[str, str], times: int) -> None:
    """Decide ``times`` of the participant's matches (side ``a``), as they would."""
    for _ in range(times):
        match = api.get("/api/participants/me/next-match", headers=me).json()
        sent = api.post(
            f"/api/matches/{match['match_id']}/label",
            headers=me,
            json={"winner": match["a"]["candidate_id"], "response_ms": 1200},
        )
        assert sent.status_code == 201, sent.text


def count(page: Page, name: str) -> Locator:
    """One number of the dashboard's counts line."""
    return page.locator(f'#live-counts [data-count="{name}"]')


def waits_for(page: Page, what: str, than: int) -> None:
    """Wait until the page's script has counted more than ``than`` of ``what``."""
    page.wait_for_function(_MORE, arg=[what, than])


def test_the_dashboard_updates_without_a_reload(
    server, browser: Browser, api: httpx.Client, screens: Path
) -> None:
    base, _ = server
    errors: list[str] = []
    created = api.post(
        "/api/studies", json={"name": "Live study", "env_id": "Hopper-v5", "n_candidates": N}
    )
    study_id = wait_until_prepared(api, created.json()["id"])["id"]
    (first_id, first), (_, second) = invite(api, study_id), invite(api, study_id)
    _, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study_id}")
    expect(count(page, "joined")).to_have_text("2")  # rendered by the server
    expect(count(page, "not_started")).to_have_text("2")
    page.evaluate("window.stillTheSamePage = true")
    waits_for(page, "unchanged", 0)  # nothing changed yet: a 304, no body

    label(api, first, 1)
    expect(count(page, "labelling")).to_have_text("1")
    row = page.locator(f'#live-table tr[data-participant-id="{first_id}"]')
    expect(row.locator("td").first).to_have_text("labelling")
    expect(row.locator(".progress-cell .small")).to_have_text("1/3")
    expect(row.locator("td").nth(2)).to_have_text("1200 ms")
    expect(page.locator('#live-rate [data-field="labels_last_minute"]')).to_have_text("1")
    expect(page.locator("#live-updated")).to_contain_text("Updated")
    assert page.evaluate("window.stillTheSamePage") is True  # updated in place

    page.click("#live-toggle")
    expect(page.locator("#live-toggle")).to_have_text("Resume updates")
    label(api, first, 2)
    label(api, second, 1)
    page.click("#live-toggle")
    expect(page.locator("#live-toggle")).to_have_text("Pause updates")
    expect(count(page, "finished")).to_have_text("1")
    expect(count(page, "labelling")).to_have_text("1")
    expect(count(page, "not_started")).to_have_text("0")
    assert page.evaluate("window.stillTheSamePage") is True
    wait_until_still(page)
    assert_accessible(page, "study page with the live dashboard")
    page.locator("#live").screenshot(path=screens / "study-live-heading.png")
    page.locator("#dashboard").screenshot(path=screens / "study-live.png")

    page.set_viewport_size(PHONE)
    updates = int(page.get_attribute("#dashboard", "data-updates") or 0)
    label(api, second, 1)
    waits_for(page, "updates", updates)
    expect(page.locator("#live-table tbody tr")).to_have_count(2)
    assert fits_width(page)  # the table scrolls inside its region
    wait_until_still(page)
    assert_accessible(page, "study page with the live dashboard, on a phone")
    assert page.evaluate("window.stillTheSamePage") is True
    assert errors == []
