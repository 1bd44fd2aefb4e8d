"""A real browser through disagreement pairs (issue 25 §5): after the bracket, the participant
is asked the pairs where their advice and a no-advice baseline disagree, one a page, on a
desktop and on a phone, then thanked; the study page says how many pairs it asks. axe-core
audits each page on each viewport, after several answers too."""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, DESKTOP, PHONE, new_page, wait_until_still
from tests.support.labelling import label_bracket, served_baseline, wait_until_prepared

pytestmark = pytest.mark.browser
PAIRS = 3


@pytest.fixture(scope="module")
def study(api: httpx.Client) -> dict[str, Any]:
    """A Hopper study asking 3 pairs, after a tiny no-advice ppo run has finished."""
    served_baseline(api)
    body = {"name": "Pairs study", "env_id": "Hopper-v5", "n_candidates": 8, "seed": 5}
    created = api.post("/api/studies", json=body | {"disagreement_pairs": PAIRS})
    assert created.status_code == 201, created.text
    return wait_until_prepared(api, created.json()["id"])


def _finished_participant(api: httpx.Client, study: dict[str, Any]) -> str:
    """A participant who finished the bracket against the baseline; their invite URL."""
    returns = {
        c["id"]: c["baseline_return"]
        for c in api.get(f"/api/studies/{study['id']}/candidates").json()
    }
    invited = api.post(f"/api/studies/{study['id']}/participants").json()

    def worse(match: dict[str, Any]) -> int:
        return min(match["a"]["candidate_id"], match["b"]["candidate_id"], key=returns.__getitem__)

    label_bracket(api, invited["token"], worse)
    return str(invited["invite_url"])


def _answer_pairs(page: Page, base: str, audit_after: tuple[int, ...], what: str) -> int:
    """Answer every pair by clicking a picture; audit the page before the answers named."""
    answered = 0
    while page.url == f"{base}/participate/pairs":
        expect(page.locator("#pair-count")).to_contain_text(f"Pair {answered + 1} of")
        wait_until_still(page)
        if answered in audit_after:
            assert_accessible(page, f"pairs page on a {what}, after {answered} answers")
        page.click("#pair-left" if answered % 2 else "#pair-right")
        page.wait_for_url(lambda url: url.endswith(("/participate/pairs", "/participate/thanks")))
        answered += 1
        assert answered <= PAIRS
    return answered


@pytest.mark.parametrize(
    ("viewport", "device"),
    [(DESKTOP, {}), (PHONE, {"is_mobile": True, "has_touch": True})],
    ids=["desktop", "phone"],
)
def test_pairs_after_the_bracket_then_thanks(
    server, browser: Browser, api: httpx.Client, study, viewport, device
) -> None:
    base, _ = server
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport, **device)
    page.goto(_finished_participant(api, study))
    page.wait_for_url(f"{base}/participate/pairs")
    total = _answer_pairs(page, base, (0, 1, 2), "phone" if device else "desktop")
    expect(page.locator("h1")).to_have_text("Thank you!")
    assert total >= 1  # the participant went against the baseline: pairs disagree
    assert_accessible(page, "thank-you page after the pairs")
    context.close()
    assert errors == []


def test_the_study_page_says_how_many_pairs_it_asks(
    server, browser: Browser, api: httpx.Client, study
) -> None:
    base, _ = server
    _finished_participant(api, study)  # the power table lists finished participants
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study['id']}")
    expect(page.get_by_text(f"{PAIRS} disagreement pairs")).to_be_visible()
    expect(page.locator("table.power caption")).to_contain_text("disagreement pairs")
    wait_until_still(page)
    assert_accessible(page, "study page of a study asking disagreement pairs")
    context.close()
    assert errors == []
