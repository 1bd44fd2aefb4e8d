"""A real browser (Playwright driving Debian's Chromium) through the whole product.

The researcher logs in, creates a 6-candidate Humanoid study and invites a participant; the
participant plays the whole bracket with taps on a phone-sized screen, then (after closing
the browser) on a desktop with the arrow keys, clicks and one undo; the thank-you page and
then the researcher's study page show the Preference Tree with thumbnails. The server is
``acv serve`` in a subprocess on 127.0.0.1 with a fresh SQLite data dir. Screenshots go to
the test's tmp dir and to ``/tmp/acv_screens``.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import (
    ADMIN_TOKEN,
    DESKTOP,
    N_CANDIDATES,
    PHONE,
    create_study_and_invite,
    fits_width,
    in_view,
    new_page,
    shown,
    wait_for_match,
)
from tests.support.server import HTTP_TIMEOUT_S

pytestmark = pytest.mark.browser

#: A log line (app.core.logs): a UTC timestamp, then the level.
LOG_LINE = re.compile(r"^\S+Z (DEBUG|INFO|WARNING|ERROR|CRITICAL)\b")


def decide(page: Page, match: str, how: str, side: str, chosen: dict[int, int]) -> None:
    """Pick ``side`` of the shown match by a key (``Arrow...``), a tap or a click."""
    chosen[int(match)] = shown(page, side)
    if how.startswith("Arrow"):
        page.keyboard.press(how)
    elif how.startswith("tap:"):
        page.tap(how.removeprefix("tap:"))
    else:
        page.click(how)


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_the_form_refuses_informative_sampling_without_a_baseline(
    server: tuple[str, Path], browser: Browser, viewport: dict[str, int]
) -> None:
    # This server trains nothing, so no no-advice ppo run exists for informative sampling.
    base, _ = server
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=viewport)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/new")
    page.fill("#name", "Informative study")
    page.select_option("#sampling", "informative")
    page.click("button:has-text('Create study')")
    expect(page.locator("p.error[role=alert]")).to_contain_text("no-advice ppo run")
    assert page.input_value("#name") == "Informative study"  # the input is kept
    assert_accessible(page, "new-study form refusing informative sampling")
    context.close()
    assert errors == [
        "Failed to load resource: the server responded with a status of 422 "
        f"(Unprocessable Entity) ({base}/studies)"
    ]


def test_participant_bracket_and_researcher_tree(
    server: tuple[str, Path], browser: Browser, screens: Path
) -> None:
    base, log = server
    errors: list[str] = []
    researcher, page = new_page(browser, errors, viewport=DESKTOP)
    study_url, invite = create_study_and_invite(page, base)
    chosen: dict[int, int] = {}  # match id -> winner the participant picked

    # Phone: instructions, then the first match by a tap; then the browser is closed.
    phone, p = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    p.goto(invite)
    p.wait_for_url(f"{base}/participate")
    p.click("#start")
    match = wait_for_match(p)
    expect(p.locator("#round-text")).to_have_text("Round 1 of 3, match 1 of 2")
    assert fits_width(p) and in_view(p, "#btn-right")
    p.screenshot(path=screens / "match-phone.png")
    decide(p, match, "tap:#pick-a", "a", chosen)
    wait_for_match(p, match)
    phone.close()

    # Desktop: the invite link resumes at the next match; keys, clicks and one undo.
    desk, d = new_page(browser, errors, viewport=DESKTOP)
    d.goto(invite)
    d.wait_for_url(f"{base}/participate/label")
    match = wait_for_match(d)
    expect(d.locator("#count-text")).to_have_text(f"1 of {N_CANDIDATES - 1} decided")
    expect(d.locator("#undo")).to_be_enabled()
    d.keyboard.press("ArrowLeft")
    match = wait_for_match(d, match)
    d.click("#undo")  # takes back the ArrowLeft label: its match is open again
    expect(d.locator("#count-text")).to_have_text(f"1 of {N_CANDIDATES - 1} decided")
    match = wait_for_match(d, match)
    expect(d.locator("#round-text")).to_have_text("Round 1 of 3, match 2 of 2")
    decide(d, match, "ArrowRight", "b", chosen)
    match = wait_for_match(d, match)
    expect(d.locator("#round-text")).to_have_text("Round 2 of 3, match 1 of 2")
    expect(d.locator("#mini-bracket .m.decided")).to_have_count(2)
    expect(d.locator("#mini-bracket .m.current")).to_have_count(1)
    assert fits_width(d) and in_view(d, "#btn-right")
    d.screenshot(path=screens / "match-desktop.png")
    decide(d, match, "#btn-left", "a", chosen)
    match = wait_for_match(d, match)
    expect(d.locator("#btn-left")).to_be_focused()  # disabled meanwhile, it gets it back
    decide(d, match, "ArrowLeft", "a", chosen)
    match = wait_for_match(d, match)
    expect(d.locator("#round-text")).to_have_text("Round 3 of 3, match 1 of 1")
    decide(d, match, "#pick-b", "b", chosen)
    d.wait_for_url(f"{base}/participate/thanks")
    expect(d.locator("#my-tree svg.pref-tree g.node")).to_have_count(N_CANDIDATES)
    expect(d.locator("#my-tree svg.pref-tree image")).to_have_count(N_CANDIDATES)
    d.screenshot(path=screens / "thanks-desktop.png", full_page=True)
    desk.close()

    # Researcher: the participant is finished and their tree is drawn with thumbnails.
    page.goto(study_url)
    expect(page.locator("table.participants tr.finished")).to_have_count(1)
    expect(page.locator("table.participants")).to_contain_text(
        f"{N_CANDIDATES - 1}/{N_CANDIDATES - 1} · finished"
    )
    tree = page.locator(".tree-box svg.pref-tree")
    expect(tree.locator("g.node")).to_have_count(N_CANDIDATES)
    expect(tree.locator("image")).to_have_count(N_CANDIDATES)
    page.screenshot(path=screens / "study-tree.png", full_page=True)
    researcher.close()

    assert _stored_labels(base, study_url) == chosen
    assert errors == []
    assert ADMIN_TOKEN not in log.read_text()  # a configured token is never printed
    # uvicorn's access log saw the invite link twice, with its token masked.
    assert log_lines_with(log, invite.rsplit("/", 1)[1]) == []
    assert len(log_lines_with(log, '"GET /p/*** HTTP/1.1" 303')) == 2


def log_lines_with(log: Path, text: str) -> list[str]:
    """Log lines (the access log included) that contain ``text``."""
    return [line for line in log.read_text().splitlines() if text in line and LOG_LINE.match(line)]


def _stored_labels(base: str, study_url: str) -> dict[int, int]:
    """match id -> winner, from the study's labels CSV (every label has a response time)."""
    study_id = study_url.rstrip("/").rsplit("/", 1)[1]
    response = httpx.get(
        f"{base}/api/studies/{study_id}/labels.csv",
        headers={"Authorization": f"Bearer {ADMIN_TOKEN}"},
        timeout=HTTP_TIMEOUT_S,
    )
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert all(row["response_ms"] != "" for row in rows)
    return {int(row["match_id"]): int(row["winner"]) for row in rows}
