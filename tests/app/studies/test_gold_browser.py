"""A real browser through gold items and "can't tell" (issue 28 §1 and §3): the researcher
adds gold items and a gate on the study page; a participant meets an instructed check (its
prompt and marker) among the bracket's matches, answers "can't tell" once, and finishes;
the quality table shows their gold accuracy and tie, and the researcher excludes a finished
participant, whose tree the study page still draws, flagged.
axe-core audits the labelling page at a gold item and after several decisions, on a desktop
and on a phone, and the study page with its gold and quality tables."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    DESKTOP,
    PHONE,
    new_page,
    researcher_page,
    wait_for_match,
    wait_until_still,
)
from tests.support.labelling import wait_until_prepared
from tests.support.studies import Player

pytestmark = pytest.mark.browser
N = 8


@pytest.fixture(scope="module")
def study(api: httpx.Client) -> dict[str, Any]:
    body = {"name": "Gold study", "env_id": "Hopper-v5", "n_candidates": N, "seed": 9}
    created = api.post("/api/studies", json=body | {"allow_ties": True})
    assert created.status_code == 201, created.text
    return wait_until_prepared(api, created.json()["id"])


def _label_through(page: Page, what: str) -> dict[str, int]:
    """Decide every match (the left picture), answer "can't tell" at the second one and
    each check as asked; audit at the first check and after three decisions."""
    seen = {"checks": 0, "decisions": 0}
    previous = None
    while "/participate/label" in page.url:
        try:
            previous = wait_for_match(page, previous)
        except Exception:  # the page left for the thank-you page meanwhile
            break
        if previous.startswith("gold-"):
            expect(page.locator("#prompt-text")).to_have_text(
                "Check: choose the picture with the marker."
            )
            names = [page.get_attribute(f"#pick-{k}", "aria-label") for k in "ab"]
            assert sorted(n.split(", ")[1] for n in names) == [
                "with the marker",
                "without the marker",
            ]
            if seen["checks"] == 0:
                assert_accessible(page, f"labelling page at a check on a {what}")
            marked = (
                "#pick-a"
                if "marker=true" in (page.get_attribute("#img-a", "src") or "")
                else "#pick-b"
            )
            page.click(marked)
            seen["checks"] += 1
            continue
        expect(page.locator("#prompt-text")).to_have_text("Which do you prefer?")
        if seen["decisions"] == 3:
            assert_accessible(page, f"labelling page after three decisions on a {what}")
        page.click("#tie" if seen["decisions"] == 1 else "#pick-a")
        seen["decisions"] += 1
        if seen["decisions"] == N - 1:
            break
    page.wait_for_url("**/participate/thanks")
    return seen


@pytest.mark.parametrize(
    ("viewport", "device", "what"),
    [(DESKTOP, {}, "desktop"), (PHONE, {"is_mobile": True, "has_touch": True}, "phone")],
    ids=["desktop", "phone"],
)
def test_a_participant_meets_a_check_and_says_cant_tell(
    server, browser: Browser, api: httpx.Client, study: dict[str, Any], viewport, device, what
) -> None:
    base, _ = server
    sid = study["id"]
    if not api.get(f"/api/studies/{sid}/gold").json():
        added = api.post(
            f"/api/studies/{sid}/gold", json={"kind": "instructed", "a": 1, "b": 2, "answer": 2}
        )
        assert added.status_code == 201, added.text
    invited = api.post(f"/api/studies/{sid}/participants").json()
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport, **device)
    page.goto(invited["invite_url"])
    expect(page.locator("#ties-note")).to_contain_text("Can't tell")
    assert_accessible(page, f"instructions of a study allowing ties on a {what}")
    page.click("#start")
    page.wait_for_url(f"{base}/participate/label")
    seen = _label_through(page, what)
    assert seen == {"checks": 1, "decisions": N - 1}
    context.close()
    assert errors == []
    quality = api.get(f"/api/studies/{sid}/quality").json()
    mine = next(p for p in quality["participants"] if p["participant_id"] == invited["id"])
    assert (mine["gold_right"], mine["gold_asked"], mine["ties"]) == (1, 1, 1)


def test_the_researcher_adds_gold_sets_a_gate_and_excludes(
    server, browser: Browser, api: httpx.Client, study: dict[str, Any]
) -> None:
    base, _ = server
    sid = study["id"]
    errors: list[str] = []
    page = researcher_page(browser, base, errors)
    page.goto(f"{base}/studies/{sid}#gold")
    page.select_option("#gold-kind", "pair")
    page.fill("#gold-a", "3")
    page.fill("#gold-b", "4")
    page.fill("#gold-answer", "5")  # refused: the page comes back with the form as typed
    page.click("#gold-form button[type=submit]")
    expect(page.locator("#gold-error")).to_contain_text("answer must be 3 or 4, got 5")
    expect(page.locator("#gold-answer")).to_have_value("5")
    wait_until_still(page)
    assert_accessible(page, "study page with a refused gold item")
    assert [e for e in errors if "422" not in e] == []  # the browser logs the refusal's 422
    errors.clear()
    page.fill("#gold-answer", "4")
    page.click("#gold-form button[type=submit]")
    expect(page.locator("#gold-table")).to_contain_text("#3 vs #4")
    page.fill("#gold_gate", "0.8")
    page.check("#gate_excludes")
    page.click("form[action$='/crowd'] button[type=submit]")
    page.wait_for_url(f"{base}/studies/{sid}#crowd")
    expect(page.locator("#gold_gate")).to_have_value("0.8")
    invited = api.post(f"/api/studies/{sid}/participants").json()
    Player(api, invited["id"], invited["token"], invited["invite_url"]).play()
    page.reload()
    row = page.locator("#quality-table tr", has_text=f"#{invited['id']}")
    row.get_by_role("button", name=f"Exclude participant #{invited['id']}").click()
    page.wait_for_url(f"{base}/studies/{sid}#quality")
    row = page.locator("#quality-table tr", has_text=f"#{invited['id']}")
    expect(row).to_contain_text("excluded by the researcher")
    assert api.get(f"/api/participants/{invited['id']}").json()["excluded"] is True
    # Left out of the trees' downloads, still drawn (and flagged) on the study page.
    heading = page.locator("h3", has_text=f"Participant #{invited['id']}")
    expect(heading.locator(".flag")).to_have_text("excluded")
    expect(page.locator(f".tree-box[data-participant-id='{invited['id']}'] svg")).to_be_visible()
    wait_until_still(page)
    assert_accessible(page, "study page with gold items, a gate and an exclusion")
    page.set_viewport_size(PHONE)
    wait_until_still(page)
    assert_accessible(page, "study page with gold items on a phone")
    assert errors == []
