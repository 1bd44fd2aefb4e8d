"""The labelling page fetches the next match's pictures while the participant decides, and
shows the next match that the label's answer carries (issue 16). A real browser (Debian's
Chromium) against ``acv serve``; axe-core checks the page."""

from __future__ import annotations

import time

import httpx
import pytest
from playwright.sync_api import Browser

from tests.support.a11y import assert_accessible
from tests.support.browser import create_study_and_invite, new_page, shown, wait_for_match
from tests.support.server import HTTP_TIMEOUT_S

pytestmark = pytest.mark.browser
PRELOAD_TIMEOUT_S = 30.0


def _following_pair(base: str, token: str, current: int) -> tuple[int, int]:
    """The players of the first undecided match after ``current`` whose players are known."""
    rounds = httpx.get(
        f"{base}/api/participants/me/bracket",
        headers={"Authorization": f"Bearer {token}"},
        timeout=HTTP_TIMEOUT_S,
    ).json()["rounds"]
    return next(
        (c["a"], c["b"])
        for cells in rounds
        for c in cells
        if not c["is_bye"]
        and c["winner"] is None
        and c["match_id"] != current
        and c["a"] is not None
        and c["b"] is not None
    )


def test_next_pictures_are_fetched_before_the_choice(server, browser: Browser) -> None:
    base, _ = server
    errors: list[str] = []
    researcher, page = new_page(browser, errors)
    study_url, invite = create_study_and_invite(page, base)
    researcher.close()
    study_id, token = study_url.rstrip("/").rsplit("/", 1)[1], invite.rsplit("/", 1)[1]
    context, p = new_page(browser, errors)
    requested: list[str] = []
    p.on("request", lambda r: requested.append(r.url))
    p.goto(invite)
    p.click("#start")
    match = wait_for_match(p)
    pair = _following_pair(base, token, int(match))
    wanted = {f"{base}/api/studies/{study_id}/candidates/{c}/image" for c in pair}
    deadline = time.monotonic() + PRELOAD_TIMEOUT_S
    while not wanted <= set(requested):  # no click yet: fetched ahead
        assert time.monotonic() < deadline, (wanted, requested)
        p.wait_for_timeout(50)
    assert_accessible(p)
    p.keyboard.press("ArrowLeft")
    wait_for_match(p, match)
    assert {shown(p, "a"), shown(p, "b")} == set(pair)
    # The sides are the server's (randomised per participant and match): `left` on the left.
    upcoming = httpx.get(
        f"{base}/api/participants/me/next-match",
        headers={"Authorization": f"Bearer {token}"},
        timeout=HTTP_TIMEOUT_S,
    ).json()
    assert shown(p, "a") == upcoming["left"]
    # One round trip per decision: the label's answer carried the match now shown.
    posted = next(k for k, u in enumerate(requested) if "/api/matches/" in u)
    assert requested[posted].endswith("/label")
    assert not any(u.endswith("/me/next-match") for u in requested[posted:])
    context.close()
    assert errors == []


def _drawn_winners(page) -> list[str]:
    """The live bracket's winners as drawn: "round:candidate" per won chip."""
    return page.eval_on_selector_all(
        "#mini-bracket .round",
        """rounds => rounds.flatMap((round, r) => [...round.querySelectorAll('.p.w')]
            .map(chip => `${r + 1}:${chip.textContent.match(/#(\\d+)/)[1]}`))""",
    )


def _server_winners(base: str, token: str) -> list[str]:
    rounds = httpx.get(
        f"{base}/api/participants/me/bracket",
        headers={"Authorization": f"Bearer {token}"},
        timeout=HTTP_TIMEOUT_S,
    ).json()["rounds"]
    return [
        f"{c['round']}:{c['winner']}"
        for cells in rounds
        for c in cells
        if c["winner"] is not None and not c["is_bye"]
    ]


def test_one_request_per_decision_and_the_bracket_kept_up_to_date(server, browser: Browser) -> None:
    """After the page has loaded, each decision is one API request (the label, whose answer
    carries the next match); the live bracket drawn from those answers is the server's."""
    base, _ = server
    errors: list[str] = []
    researcher, page = new_page(browser, errors)
    _, invite = create_study_and_invite(page, base)
    researcher.close()
    token = invite.rsplit("/", 1)[1]
    context, p = new_page(browser, errors)
    p.goto(invite)
    p.click("#start")
    match = wait_for_match(p)
    api_calls: list[str] = []
    p.on(
        "request",
        lambda r: (
            api_calls.append(f"{r.method} {r.url}")
            if "/api/" in r.url and "/image" not in r.url
            else None
        ),
    )
    decisions = 0
    while True:
        p.keyboard.press("ArrowRight" if decisions % 2 else "ArrowLeft")
        decisions += 1
        try:
            match = wait_for_match(p, match)
        except Exception:  # the last decision leads to the thank-you page
            break
        assert sorted(_drawn_winners(p)) == sorted(_server_winners(base, token))
    p.wait_for_url(f"{base}/participate/thanks")
    labelling = [c for c in api_calls if not c.endswith("/tree")]  # the thank-you page's tree
    assert len(labelling) == decisions, api_calls
    assert all(c.startswith("POST") and c.endswith("/label") for c in labelling), api_calls
    context.close()
    assert errors == []
