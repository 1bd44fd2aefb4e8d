"""A real browser through an open link's seats, time limit and per-outcome codes (issue 45
§1-2), on a desktop and on a phone. The researcher sets the link up with the study page's
form (consent text, a decline code, a time limit, a redirect URL with ``{code}``). Then:

1. a visitor declines consent: the declined page shows the decline code and the way back to
   the platform with the code in the URL;
2. a visitor's time runs out (their deadline moved into the past in the server's database,
   as a clock moving on): their next pick lands on "Your time is over", with no code; the
   open link, visited again with the same platform ids (in the same browser and another),
   shows that page again and takes no second seat;
3. a visitor joins (the timed-out seat is freed for them), decides one match, follows
   "Withdraw from this study", confirms, and lands on the ended page with the decline code;
   the bracket sends them back there, and their seat is free again;
4. the study page's dashboard counts the withdrawn and the timed-out participant;
5. the researcher adds two check pairs (gold items) and, in the form, a gold gate that excludes
   with a code of its own; a careless visitor picks the wrong picture of both check pairs, and
   their next pick lands on "This study has ended for you" with the gate's code (issue 28 §3);
   their outcome is ``failed_gate``.

axe-core checks every page once it is settled (screenshots: /tmp/acv_screens).
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Locator, Page, Response, expect
from sqlalchemy import update

from app.core.auth import PARTICIPANT_COOKIE
from app.db import make_engine
from app.models import Member, utcnow
from app.settings import SQLITE_FILE
from tests.support.a11y import assert_accessible
from tests.support.browser import (
    ADMIN_TOKEN,
    DESKTOP,
    PHONE,
    fits_width,
    new_page,
    wait_for_match,
    wait_until_still,
)
from tests.support.labelling import wait_until_prepared

pytestmark = pytest.mark.browser
COMPLETION, DECLINE, GATE = "C0MPL3TE", "D3CL1NE", "G4T3ST0P"
#: The check pairs of step 5 (as in tests/app/studies/test_gold_ties.py): a plain one, and an
#: instructed one (pick the picture with the marker).
GOLD = [
    {"kind": "pair", "a": 0, "b": 1, "answer": 1},
    {"kind": "instructed", "a": 2, "b": 3, "answer": 2},
]
TIME_LIMIT_MIN = 30
#: What Chromium logs for the one label POST refused with 410 (the timed-out pick).
GONE = "status of 410"
#: What the confirm form's POST answering other than its redirect means (it answered 500 on
#: SQLite while app/recruiting/seats.py's UPDATEs synchronized the session by evaluating
#: ``deadline_at > now`` in Python: SQLite's naive datetimes against an aware ``now``).
WITHDRAW_FAILED = "POST /participate/withdraw answered {} (see the server log), not its 303"


def settled(page: Page, what: str) -> None:
    """axe-core on ``page`` once nothing on it animates; it fits the window's width."""
    wait_until_still(page)
    assert fits_width(page), f"{what}: wider than the window"
    assert_accessible(page, what)


def set_up_link(page: Page, base: str, study_id: int, platform: str) -> str:
    """Fill the study page's open-link form; returns the open link it then shows."""
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study_id}")
    page.check("#crowd-enabled")
    page.fill("#max_participants", "5")
    page.fill("#consent_text", "We store your choices and your Prolific id, nothing else.")
    page.fill("#completion_code", COMPLETION)
    page.fill("#decline_code", DECLINE)
    page.fill("#time_limit_min", str(TIME_LIMIT_MIN))
    page.fill("#redirect_url", f"{platform}/submissions/complete?cc={{code}}")
    page.click("text=Save open link")
    page.wait_for_url(f"{base}/studies/{study_id}#crowd")
    expect(page.locator("#decline_code")).to_have_value(DECLINE)
    expect(page.locator("#time_limit_min")).to_have_value(str(TIME_LIMIT_MIN))
    settled(page, "study page with the open link's codes and time limit")
    return page.inner_text("#open-link")


def ids(pid: str) -> str:
    """Prolific's query parameters for one attempt of ``pid``."""
    return f"?PROLIFIC_PID={pid}&STUDY_ID=st&SESSION_ID=se-{pid}"


def join(page: Page, base: str, link: str, pid: str, audit: str | None = None) -> str:
    """Consent as ``pid`` and start the bracket; the first match's id, once settled. With
    ``audit``, the instructions page (its time left) is checked by axe-core first."""
    page.goto(link + ids(pid))
    expect(page.locator("#consent-text")).to_contain_text("Prolific id")
    expect(page.locator("#time-limit")).to_contain_text(f"{TIME_LIMIT_MIN} minutes to finish")
    page.click("#agree")
    page.wait_for_url(f"{base}/participate")
    if audit is not None:
        expect(page.locator("#time-left")).to_contain_text("minutes")
        settled(page, audit)
    page.click("#start")
    page.wait_for_url(f"{base}/participate/label")
    return wait_for_match(page)


def joined(api: httpx.Client, study_id: int) -> int:
    """Seats of the open link in use now."""
    return api.get(f"/api/studies/{study_id}/crowd").json()["joined"]


def time_runs_out(log: Path, study_id: int, pid: str) -> None:
    """Move ``pid``'s deadline a minute into the past in the server's database (the
    ``server`` fixture's SQLite file sits beside its log), as the clock passing it would."""
    engine = make_engine(f"sqlite:///{log.parent / SQLITE_FILE}")
    try:
        with engine.begin() as conn:
            moved = conn.execute(
                update(Member)
                .where(
                    Member.collection_kind == "study",
                    Member.collection_id == study_id,
                    Member.external_id == pid,
                    Member.deadline_at.is_not(None),  # the link gave them a time limit
                )
                .values(deadline_at=utcnow() - timedelta(minutes=1))
            )
            assert moved.rowcount == 1
    finally:
        engine.dispose()


def withdraw_post(base: str) -> Callable[[Response], bool]:
    """Whether a response is the confirm form's POST (its 303, before the redirect)."""
    url = f"{base}/participate/withdraw"
    return lambda response: response.url == url and response.request.method == "POST"


def expect_ended(page: Page, title: str, code: str | None, platform: str) -> None:
    """The ended page: ``title``, and ``code`` with the way back (or neither)."""
    expect(page.locator("h1")).to_have_text(title)
    if code is None:
        expect(page.locator("#completion-code")).to_have_count(0)
        expect(page.locator("#complete-link")).to_have_count(0)
    else:
        expect(page.locator("#completion-code")).to_have_text(code)
        link = f"{platform}/submissions/complete?cc={code}"
        expect(page.locator("#complete-link")).to_have_attribute("href", link)


def add_gold(api: httpx.Client, study_id: int) -> dict[int, int]:
    """Add :data:`GOLD` to the study; each item's id with its wrong answer."""
    wrong = {}
    for body in GOLD:
        made = api.post(f"/api/studies/{study_id}/gold", json=body)
        assert made.status_code == 201, made.text
        wrong[made.json()["id"]] = ({body["a"], body["b"]} - {body["answer"]}).pop()
    return wrong


def set_gate(page: Page, base: str, study_id: int, link: str) -> None:
    """Give the open link, in the study page's form, a gold gate that excludes whom it flags
    (and so stops them after 2 failed check pairs) with :data:`GATE` as their code."""
    page.goto(f"{base}/studies/{study_id}")
    page.fill("#gold_gate", "0.9")
    page.check("#gate_excludes")
    page.fill("#gate_code", GATE)
    page.click("text=Save open link")
    page.wait_for_url(f"{base}/studies/{study_id}#crowd")
    expect(page.locator("#gold_gate")).to_have_value("0.9")
    expect(page.locator("#gate_excludes")).to_be_checked()
    expect(page.locator("#gate_code")).to_have_value(GATE)
    expect(page.locator("#open-link")).to_have_text(link)  # the same link, the same codes
    expect(page.locator("#decline_code")).to_have_value(DECLINE)


def fail_the_checks(page: Page, shown: str, wrong: dict[int, int]) -> str:
    """From the match ``shown``: the left picture of each bracket match and the wrong one of
    each check pair (``wrong``: :func:`add_gold`'s), until every check pair is answered; the
    bracket match shown then, once settled."""
    answered = 0
    while answered < len(wrong):
        if shown.startswith("gold-"):  # static/js/label.js's key of a check pair
            loser = f'img[alt="candidate {wrong[int(shown.removeprefix("gold-"))]}"]'
            page.locator("#match .pick", has=page.locator(loser)).click()
            answered += 1
        else:
            page.click("#pick-a")
        shown = wait_for_match(page, shown)
    assert not shown.startswith("gold-"), shown
    return shown


def participant_id(api: httpx.Client, page: Page, study_id: int) -> int:
    """The id of the participant whose invitation ``page``'s browser holds (its cookie)."""
    token = next(c["value"] for c in page.context.cookies() if c["name"] == PARTICIPANT_COOKIE)
    people = api.get(f"/api/studies/{study_id}/participants").json()
    return next(p["id"] for p in people if p["token"] == token)


def live_status(page: Page, pid: str) -> Locator:
    """The status cell of ``pid``'s row in the dashboard's table."""
    return page.locator("#live-table tbody tr", has_text=pid).locator("td").first


@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_decline_time_out_withdraw_and_the_dashboard(
    server,
    browser: Browser,
    api: httpx.Client,
    screens: Path,
    platform: str,
    viewport: dict[str, int],
) -> None:
    base, log = server
    where = "on a phone" if viewport == PHONE else "on a desktop"
    errors: list[str] = []
    created = api.post(
        "/api/studies",
        json={"name": "Seats study", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 3},
    )
    assert created.status_code == 201, created.text
    study_id = wait_until_prepared(api, created.json()["id"])["id"]
    _, researcher = new_page(browser, errors, viewport=viewport)
    link = set_up_link(researcher, base, study_id, platform)
    assert link.startswith(f"{base}/s/")

    # (1) Declining consent: the decline code, and the way back with the code in its URL.
    _, d = new_page(browser, errors, viewport=viewport)
    d.goto(link + ids("decliner"))
    expect(d.locator("#consent-text")).to_contain_text("Prolific id")
    settled(d, f"consent page {where}")
    d.click("#decline")
    expect_ended(d, "You declined", DECLINE, platform)
    settled(d, f"declined page with its code {where}")
    d.screenshot(path=screens / f"seats-declined-{viewport['width']}.png", full_page=True)
    d.click("#complete-link")
    d.wait_for_url(f"{platform}/submissions/complete?cc={DECLINE}")
    expect(d.locator("h1")).to_have_text("Submission complete")

    # (2) Out of time: the next pick is refused (410) and the page says so, with no code.
    _, t = new_page(browser, errors, viewport=viewport)
    join(t, base, link, "late")
    time_runs_out(log, study_id, "late")
    t.click("#pick-a")
    t.wait_for_url(f"{base}/participate/ended")
    expect_ended(t, "Your time is over", None, platform)
    settled(t, f"ended page after the time ran out {where}")
    t.screenshot(path=screens / f"seats-timed-out-{viewport['width']}.png", full_page=True)
    gone = [e for e in errors if GONE in e]
    assert len(gone) == 1, errors  # Chromium logs the refused pick's status; nothing else
    errors[:] = [e for e in errors if GONE not in e]
    seats_before = joined(api, study_id)
    t.goto(link + ids("late"))  # the same browser, by the same platform ids
    t.wait_for_url(f"{base}/participate/ended")
    expect_ended(t, "Your time is over", None, platform)
    _, again = new_page(browser, errors, viewport=viewport)  # another browser, same ids
    again.goto(link + ids("late"))
    again.wait_for_url(f"{base}/participate/ended")
    expect_ended(again, "Your time is over", None, platform)
    settled(again, f"ended page on coming back after the time {where}")
    assert joined(api, study_id) <= seats_before  # never a second seat

    # (3) Withdrawing after a label: a confirm page, then the ended page with the code.
    _, w = new_page(browser, errors, viewport=viewport)
    first = join(w, base, link, "withdrawer", audit=f"instructions with the time left {where}")
    assert joined(api, study_id) == 1  # the late one's seat was freed by this join
    settled(w, f"labelling page with the withdraw link {where}")
    w.click("#pick-a")
    wait_for_match(w, first)
    w.click("#withdraw-link")
    w.wait_for_url(f"{base}/participate/withdraw")
    expect(w.locator("h1")).to_have_text("Withdraw from this study?")
    expect(w.locator("#keep-going")).to_have_attribute("href", "/participate/label")
    settled(w, f"withdraw confirm page {where}")
    with w.expect_response(withdraw_post(base)) as posted:
        w.click("#withdraw")
    assert posted.value.status == 303, WITHDRAW_FAILED.format(posted.value.status)
    w.wait_for_url(f"{base}/participate/ended")
    expect_ended(w, "You withdrew", DECLINE, platform)
    settled(w, f"ended page after withdrawing {where}")
    w.screenshot(path=screens / f"seats-withdrew-{viewport['width']}.png", full_page=True)
    w.goto(f"{base}/participate/label")
    w.wait_for_url(f"{base}/participate/ended")
    expect_ended(w, "You withdrew", DECLINE, platform)
    assert joined(api, study_id) == 0  # the withdrawer's seat is free again

    # (4) The dashboard counts the withdrawn and the timed-out participant.
    researcher.goto(f"{base}/studies/{study_id}#live")
    counts = researcher.locator("#live-counts")
    expect(counts.locator('[data-count="joined"]')).to_have_text("2")
    expect(counts.locator('[data-count="declined"]')).to_have_text("1")
    expect(counts.locator('[data-count="withdrawn"]')).to_have_text("1")
    expect(counts.locator('[data-count="timed_out"]')).to_have_text("1")
    expect(counts.locator('[data-count="finished"]')).to_have_text("0")
    expect(counts).to_contain_text("1 withdrew")
    expect(counts).to_contain_text("1 timed out")
    expect(live_status(researcher, "late")).to_have_text("timed out")
    expect(live_status(researcher, "withdrawer")).to_have_text("withdrawn")
    settled(researcher, f"study page with the withdrawn and timed-out counts {where}")
    researcher.locator("#dashboard").screenshot(
        path=screens / f"seats-dashboard-{viewport['width']}.png"
    )

    # (5) The gold gate: two check pairs answered wrong stop a careless visitor; their next
    # pick is refused (410) and the page says the study has ended for them, with the code.
    wrong = add_gold(api, study_id)  # given to those who join from now on
    set_gate(researcher, base, study_id, link)
    _, g = new_page(browser, errors, viewport=viewport)
    last = fail_the_checks(g, join(g, base, link, "careless"), wrong)
    g.click("#pick-a")
    g.wait_for_url(f"{base}/participate/ended")
    expect_ended(g, "This study has ended for you", GATE, platform)
    expect(g.locator(".card")).to_contain_text("answers to the check pairs were not the")
    settled(g, f"ended page after the gold gate {where}")
    g.screenshot(path=screens / f"seats-failed-gate-{viewport['width']}.png", full_page=True)
    g.goto(link + ids("careless"))  # back from the platform by the same ids
    g.wait_for_url(f"{base}/participate/ended")
    expect_ended(g, "This study has ended for you", GATE, platform)
    gone = [e for e in errors if GONE in e]
    assert len(gone) == 1, errors  # the refused pick's status; nothing else
    errors[:] = [e for e in errors if GONE not in e]
    person = api.get(f"/api/participants/{participant_id(api, g, study_id)}").json()
    assert (person["outcome"], person["code"]) == ("failed_gate", GATE), person
    assert person["excluded"] and person["exclusion_reason"].startswith("gold gate: 0 of 2")
    # 4 candidates: the check pairs come after the 1st and the 2nd match; the 3rd was refused
    assert person["progress"]["done"] == 2, (last, person)
    assert joined(api, study_id) == 0  # the stopped visitor's seat is free again
    researcher.goto(f"{base}/studies/{study_id}")
    expect(live_status(researcher, "careless")).to_have_text("failed gate")
    expect(researcher.locator('[data-count="timed_out"]')).to_have_text("1")  # not the gated
    settled(researcher, f"study page with a participant the gate stopped {where}")
    assert errors == []
