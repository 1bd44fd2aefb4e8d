"""Clips on the pairs after the bracket in a real browser (issue 41 §3), on a desktop and on a
phone: in a study whose clips are rendered, the disagreement pairs and the consistency check
play both candidates' clips, pausing one swaps it for its still, a key press or a tap answers
as ever and the answer records the clip; with reduced motion the stills show, each with a
Play control, and an answer given on them records stills. Without JavaScript the stills show
and the forms still answer. axe-core audits every state."""

from __future__ import annotations

import json
import re
import sqlite3
from contextlib import closing
from pathlib import Path
from typing import Any

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from app.settings import SQLITE_FILE
from tests.support.a11y import assert_accessible
from tests.support.browser import DESKTOP, PHONE, fits_width, new_page, wait_until_still
from tests.support.labelling import label_bracket, served_baseline, wait_until_prepared
from tests.support.wait import wait_for

pytestmark = pytest.mark.browser
CLIP, STILL = re.compile(r"/clip$"), re.compile(r"/image$")
PAIRS_PATH, CHECK_PATH = "/participate/pairs", "/participate/check"


@pytest.fixture(scope="module")
def study(api: httpx.Client) -> dict[str, Any]:
    """A 4-candidate Hopper study with clips, asking 2 disagreement pairs and the consistency
    check, after a tiny no-advice ppo run has finished; its clips rendered."""
    served_baseline(api)
    body = {"name": "Clip pairs", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 7}
    created = api.post("/api/studies", json=body | {"disagreement_pairs": 2, "clips": True})
    assert created.status_code == 201, created.text
    study_id = created.json()["id"]
    wait_until_prepared(api, study_id)
    crowd = {"enabled": True, "max_participants": 50, "consistency_check": True}
    assert api.put(f"/api/studies/{study_id}/crowd", json=crowd).status_code == 200
    ready = wait_for(
        lambda: api.get(f"/api/studies/{study_id}").json(),
        lambda s: s["clips_ready"] or s["error"],
        what="the study's clips",
        timeout_s=300,
        every_s=0.5,
    )
    assert ready["clips_ready"], ready
    return ready


def _finished(api: httpx.Client, study: dict[str, Any]) -> tuple[int, str]:
    """A participant who finished the bracket against the baseline: their id and invite URL."""
    returns = {
        c["id"]: c["baseline_return"]
        for c in api.get(f"/api/studies/{study['id']}/candidates").json()
    }
    invited = api.post(f"/api/studies/{study['id']}/participants").json()
    label_bracket(
        api,
        invited["token"],
        lambda m: min(m["a"]["candidate_id"], m["b"]["candidate_id"], key=returns.__getitem__),
    )
    return int(invited["id"]), str(invited["invite_url"])


def _stored(log: Path, pid: int) -> tuple[list[str], list[str]]:
    """What the participant's answered disagreement pairs and check showed, as stored."""
    with closing(sqlite3.connect(log.parent / SQLITE_FILE)) as db:
        pairs = db.execute(
            "SELECT stimulus FROM disagreement_pairs WHERE participant_id = ? "
            "AND winner IS NOT NULL ORDER BY position",
            (pid,),
        ).fetchall()
        check = db.execute(
            "SELECT stimulus FROM consistency_checks WHERE participant_id = ? "
            "AND winner IS NOT NULL",
            (pid,),
        ).fetchall()
    return [s for (s,) in pairs], [s for (s,) in check]


def _exported(api: httpx.Client, study: dict[str, Any], pid: int) -> list[str]:
    """The stimulus of the participant's disagreement rows in the labels export."""
    lines = api.get(f"/api/studies/{study['id']}/export/labels.jsonl").text.splitlines()
    rows = [json.loads(line) for line in lines]
    return [
        r["stimulus"] for r in rows if (r["participant_id"], r["kind"]) == (pid, "disagreement")
    ]


def _settled(page: Page) -> None:
    """Wait until the pair's script has set up its toggles and nothing animates."""
    expect(page.locator("form.check-pair")).to_have_attribute("data-ready", "true")
    wait_until_still(page)


def audited(page: Page, what: str) -> None:
    assert fits_width(page), f"{what}: wider than the window"
    assert_accessible(page, what)


def _sides(page: Page, prefix: str, left: re.Pattern[str], right: re.Pattern[str]) -> None:
    """Each side's picture is its clip or its still, and its toggle says what it does."""
    for side, shows in (("left", left), ("right", right)):
        expect(page.locator(f"#{prefix}-img-{side}")).to_have_attribute("src", shows)
        verb = "Pause" if shows is CLIP else "Play"
        expect(page.locator(f"#{prefix}-motion-{side}")).to_have_text(
            f"{verb} the {side} candidate"
        )


def _answer(page: Page, prefix: str, by_key: bool) -> None:
    """Answer the pair on screen: Enter on the right picture, or a click on the left one."""
    with page.expect_navigation():
        if by_key:
            page.focus(f"#{prefix}-right")
            page.keyboard.press("Enter")
        else:
            page.click(f"#{prefix}-left")


@pytest.mark.parametrize(
    ("viewport", "device"),
    [(DESKTOP, {}), (PHONE, {"is_mobile": True, "has_touch": True})],
    ids=["desktop", "phone"],
)
def test_the_pairs_and_the_check_play_clips_pause_and_record_them(
    server, browser: Browser, api: httpx.Client, study, viewport, device
) -> None:
    base, log = server
    where = "on a phone" if device else "on a desktop"
    pid, url = _finished(api, study)
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport, **device)
    page.goto(url)
    page.wait_for_url(f"{base}{PAIRS_PATH}")
    answered = 0
    while page.url == f"{base}{PAIRS_PATH}":
        expect(page.locator("#pair-count")).to_contain_text(f"Pair {answered + 1} of")
        _settled(page)
        _sides(page, "pair", CLIP, CLIP)
        audited(page, f"a disagreement pair with clips playing {where}")
        page.click("#pair-motion-left")  # pausing swaps the clip for its still
        _sides(page, "pair", STILL, CLIP)
        audited(page, f"a disagreement pair with the left clip paused {where}")
        _answer(page, "pair", by_key=answered == 0)  # the keyboard, then a click or tap
        answered += 1
        assert answered <= 2
    page.wait_for_url(f"{base}{CHECK_PATH}")
    _settled(page)
    _sides(page, "check", CLIP, CLIP)
    audited(page, f"the consistency check with clips playing {where}")
    page.click("#check-motion-right")
    _sides(page, "check", CLIP, STILL)
    audited(page, f"the consistency check with the right clip paused {where}")
    _answer(page, "check", by_key=False)
    page.wait_for_url(f"{base}/participate/thanks")
    assert answered >= 1  # the participant went against the baseline: pairs disagree
    assert _stored(log, pid) == (["clip"] * answered, ["clip"])
    assert _exported(api, study, pid) == ["clip"] * answered
    context.close()

    # Reduced motion: the stills, each with a Play control; an answer on them records stills.
    calm_id, calm_url = _finished(api, study)
    context, calm = new_page(browser, errors, viewport=viewport, reduced_motion="reduce", **device)
    calm.goto(calm_url)
    calm.wait_for_url(f"{base}{PAIRS_PATH}")
    shown: list[str] = []
    while calm.url == f"{base}{PAIRS_PATH}":
        _settled(calm)
        _sides(calm, "pair", STILL, STILL)
        audited(calm, f"a disagreement pair with reduced motion {where}")
        if not shown:  # the first pair: its left clip played, on request
            calm.click("#pair-motion-left")
            _sides(calm, "pair", CLIP, STILL)
            audited(calm, f"a disagreement pair with reduced motion, a clip played {where}")
        shown.append("still" if shown else "clip")
        _answer(calm, "pair", by_key=len(shown) == 1)
    calm.wait_for_url(f"{base}{CHECK_PATH}")
    _settled(calm)
    _sides(calm, "check", STILL, STILL)
    audited(calm, f"the consistency check with reduced motion {where}")
    _answer(calm, "check", by_key=True)
    calm.wait_for_url(f"{base}/participate/thanks")
    assert _stored(log, calm_id) == (shown, ["still"])
    assert _exported(api, study, calm_id) == shown
    context.close()
    assert errors == []


def test_without_javascript_the_pairs_show_stills_and_still_answer(
    server, browser: Browser, api: httpx.Client, study
) -> None:
    base, log = server
    pid, url = _finished(api, study)
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP, java_script_enabled=False)
    page.goto(url)
    page.wait_for_url(f"{base}{PAIRS_PATH}")
    answered = 0
    while page.url == f"{base}{PAIRS_PATH}":
        expect(page.locator("#pair-img-left")).to_have_attribute("src", STILL)
        expect(page.locator("#pair-motion-left")).to_be_hidden()
        _answer(page, "pair", by_key=False)
        answered += 1
        assert answered <= 2
    page.wait_for_url(f"{base}{CHECK_PATH}")
    expect(page.locator("#check-img-right")).to_have_attribute("src", STILL)
    expect(page.locator("#check-motion-right")).to_be_hidden()
    _answer(page, "check", by_key=False)
    page.wait_for_url(f"{base}/participate/thanks")
    assert _stored(log, pid) == (["still"] * answered, ["still"])
    context.close()
    assert errors == []
