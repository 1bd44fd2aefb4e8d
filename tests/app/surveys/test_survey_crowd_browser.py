"""A real browser through a crowd survey (issue 14): the researcher opens the survey's link
with the survey page's form; a visitor arrives with Prolific's query parameters, consents,
answers both screens, sees the completion code and is sent to the completion URL (a local
page, :func:`tests.app.studies.test_crowd_browser.platform`). Another visitor declines; a third
finds the survey full. axe-core checks every page added or changed.

The request of the completion URL is held (a Playwright route) until the thank-you screen
has been checked, so the redirect never races the checks, whatever the machine's speed.
"""

from __future__ import annotations

from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, Route, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, new_page
from tests.support.crowd import turned_away
from tests.support.server import HTTP_TIMEOUT_S
from tests.support.surveys import READY, paper_body, two_finished_participants

pytestmark = pytest.mark.browser

ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
DESKTOP = {"width": 1280, "height": 900}
CODE = "C0MPL3TE"


class Gate:
    """Holds the completion URL's request (a Playwright route) until :meth:`open`; the
    handler runs whenever Playwright handles events, before or after the opening."""

    def __init__(self) -> None:
        self.is_open, self.held = False, []

    def hold(self, route: Route) -> None:
        if self.is_open:
            route.continue_()
        else:
            self.held.append(route)

    def open(self) -> None:
        self.is_open = True
        for route in self.held:
            route.continue_()


def two_stimulus_survey(base: str) -> int:
    """A paper survey (API) with two stimuli and no attention check: two screens."""
    study_id = two_finished_participants(base)
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        people = api.get(f"/api/studies/{study_id}/participants").json()
        one, two = ({"kind": "participant", "participant_id": p["id"]} for p in people[:2])
        stimuli = [
            {"label": "Case A", "tree1": one, "tree2": two},
            {"label": "Case B", "tree1": two, "tree2": one},
        ]
        body = paper_body(one, two, name="Crowd survey", stimuli=stimuli, attention_check=None)
        response = api.post("/api/surveys", json=body)
        assert response.status_code == 201, response.text
        return response.json()["id"]


def open_the_link(page: Page, base: str, survey_id: int, platform: str) -> str:  # noqa: F811
    """Fill the survey page's open-link form; returns the open link it then shows."""
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/surveys/{survey_id}")
    page.check("#crowd-enabled")
    page.fill("#max_participants", "1")
    page.fill("#consent_text", "We store your answers and your Prolific id, nothing else.")
    page.fill("#completion_code", CODE)
    page.fill("#redirect_url", f"{platform}/submissions/complete?cc={CODE}")
    page.click("text=Save open link")
    page.wait_for_url(f"{base}/surveys/{survey_id}#crowd")
    expect(page.locator("#joined")).to_have_text("0 of 1 joined")
    return page.inner_text("#open-link")


def answer(p: Page) -> None:
    """Choose an answer and a confidence for each question of the shown screen, submit."""
    p.wait_for_function(READY)
    position = p.get_attribute("#respond", "data-position")
    for key in ("q1", "q2"):
        p.click(f"fieldset[data-key={key}] .choices:not(.scale) label >> nth=0")
        p.click(f"fieldset[data-key={key}] .confidence label:has(input[value='4'])")
    p.click("#submit")
    p.wait_for_function(
        "prev => { const r = document.getElementById('respond'); return "
        "r.dataset.finished === 'true' || (r.dataset.ready === 'true' && "
        "r.dataset.position !== prev); }",
        arg=position,
    )


def test_open_link_consent_screens_and_completion(
    server,  # noqa: F811
    browser: Browser,  # noqa: F811
    platform: str,  # noqa: F811
) -> None:
    base, _ = server
    errors: list[str] = []
    survey_id = two_stimulus_survey(base)
    _, page = new_page(browser, errors, viewport=DESKTOP)
    link = open_the_link(page, base, survey_id, platform)
    assert link.startswith(f"{base}/q/")
    assert_accessible(page, "survey page with the open-link form")

    context, p = new_page(browser, errors, viewport=DESKTOP)
    gate = Gate()
    p.route(f"{platform}/**", gate.hold)
    p.goto(f"{link}?PROLIFIC_PID=pw-1&STUDY_ID=st&SESSION_ID=se")
    expect(p.locator("#consent-text")).to_contain_text("Prolific id")
    expect(p.locator(".study-name")).to_have_text("Crowd survey")
    assert_accessible(p, "survey consent page")
    p.click("#agree")
    p.wait_for_url(f"{base}/survey")
    expect(p.locator("#intro")).to_be_visible()
    assert_accessible(p, "survey intro through the open link")
    p.click("#start")
    p.wait_for_function(READY)
    expect(p.locator("#screen-title")).to_have_text("Screen 1 of 2")
    assert_accessible(p, "survey screen through the open link")
    answer(p)
    expect(p.locator("#screen-title")).to_have_text("Screen 2 of 2")
    answer(p)
    expect(p.locator("#done")).to_be_visible()
    expect(p.locator("#completion-code")).to_have_text(CODE)
    expect(p.locator("#complete-link")).to_be_visible()
    expect(p.locator("#stay-here")).to_be_visible()  # the person may stop the way back
    assert_accessible(p, "survey thank-you screen with the completion code")
    gate.open()  # left alone, the page goes back by itself (after 20 s)
    p.wait_for_url(f"{platform}/submissions/complete?cc={CODE}", timeout=60_000)
    expect(p.locator("h1")).to_have_text("Submission complete")
    context.close()

    _, d = new_page(browser, errors, viewport=DESKTOP)
    d.goto(f"{link}?PROLIFIC_PID=pw-2")  # the one place is taken: no consent page
    expect(d.locator("h1")).to_have_text("This survey is full")
    assert_accessible(d, "survey full page")

    with httpx.Client(
        base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S
    ) as api:  # one place more
        url = f"/api/surveys/{survey_id}/crowd"
        settings = api.get(url).json()
        kept = {k: settings[k] for k in ("enabled", "consent_text", "external_params")}
        assert api.put(url, json=kept | {"max_participants": 2}).status_code == 200
    _, n = new_page(browser, errors, viewport=DESKTOP)
    n.goto(f"{link}?PROLIFIC_PID=pw-3")
    n.click("#decline")
    expect(n.locator("h1")).to_have_text("You declined")
    assert_accessible(n, "survey declined page")

    turned_away(browser, errors, link, f"{base}/api/surveys/{survey_id}/crowd")

    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        crowd: dict[str, Any] = api.get(f"/api/surveys/{survey_id}/crowd").json()
        rows = api.get(f"/api/surveys/{survey_id}/answers.jsonl").text.splitlines()
    assert (crowd["joined"], crowd["declines"], crowd["completed"]) == (1, 1, 1)
    assert len(rows) == 4 and all('"external_id": "pw-1"' in r for r in rows)
    assert errors == []
