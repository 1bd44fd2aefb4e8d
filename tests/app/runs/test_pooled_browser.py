"""A real browser (Debian's Chromium through Playwright) on pooled advice: the researcher
launches a run on two finished participants ticked in the new-run form, weighted by
reliability; the run page lists each pooled participant's weight, and the comparison page
shows the agent against each participant's tree and against the pooled verdict. axe-core
checks the three pages (no serious or critical violation).
"""

from __future__ import annotations

import re

import httpx
import pytest
from playwright.sync_api import Browser, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, new_page
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.surveys import two_finished_participants
from tests.support.wait import wait_for

pytestmark = [pytest.mark.browser, pytest.mark.training]

ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}


def test_a_run_on_pooled_advice_from_the_form_to_the_comparison(
    server, browser: Browser, screens
) -> None:
    base = server[0]
    study_id = two_finished_participants(base)
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        people = sorted(p["id"] for p in api.get(f"/api/studies/{study_id}/participants").json())
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport={"width": 1280, "height": 900})
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/runs/new?study_id={study_id}")
    expect(page.locator("fieldset.pool input[type=checkbox]")).to_have_count(2)
    assert_accessible(page, "new-run form with a pool")
    page.select_option("#advice", "pool:chosen")
    for pid in people:
        page.check(f"input[name=pool_{pid}]")
    page.select_option("#pool_weighting", "reliability")
    page.fill("#timesteps", "256")
    page.fill("#n_envs", "1")
    page.fill("#num_steps", "128")
    page.uncheck("#experiment")  # one pooled run, not an experiment
    page.click("text=Start training")
    page.wait_for_url(re.compile(rf"{base}/runs/\d+$"))
    run_id = int(page.url.rstrip("/").rsplit("/", 1)[1])
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        run = wait_for(
            lambda: api.get(f"/api/runs/{run_id}").json(),
            lambda r: r["status"] not in ("queued", "running"),
            what=f"run {run_id}",
            timeout_s=180,
        )
        assert run["status"] == "succeeded" and run["participant_ids"] == people, run
        assert run["pool_weighting"] == "reliability", run
        advisors = api.get(f"/api/runs/{run_id}/advisors").json()
    # run.js reloads the page itself when the run ends; a reload of ours could race with
    # it. Wait for the page the server rendered for the finished run instead.
    expect(page.locator("#run")).to_have_attribute("data-status", "succeeded", timeout=30_000)
    weights = page.locator("#pool-weights tbody tr")
    expect(weights).to_have_count(2)
    for i, w in enumerate(run["pool_weights"]):
        expect(weights.nth(i).locator("th")).to_have_text(f"participant #{w['participant_id']}")
        expect(weights.nth(i).locator("td").first).to_have_text(f"{w['weight']:.2f}")
    assert_accessible(page, "run page of a reliability-weighted pool")
    page.locator("#pool-weights").screenshot(path=screens / "run-pool-weights.png")
    page.goto(f"{base}/runs/{run_id}/compare")
    rows = page.locator("#advisors-body tr")
    expect(rows).to_have_count(3)
    for i, advisor in enumerate(advisors["advisors"]):
        m = advisor["conformance"]
        expect(rows.nth(i).locator("th")).to_have_text(f"participant #{advisor['participant_id']}")
        expect(rows.nth(i).locator("td").nth(1)).to_have_text(f"{m['n_agree']} / {m['n_matches']}")
    pooled = advisors["pooled"]
    expect(rows.nth(2).locator("th")).to_have_text("pooled verdict")
    expect(rows.nth(2).locator("td").nth(1)).to_have_text(
        f"{pooled['n_agree']} / {pooled['n_matches']}"
    )
    expect(page.locator("#advisors caption")).to_have_text(
        "The agent against each participant, and against the pooled verdict"
    )
    assert_accessible(page, "compare page of a pooled run")
    page.screenshot(path=screens / "compare-pooled.png", full_page=True)
    assert errors == []
    context.close()
