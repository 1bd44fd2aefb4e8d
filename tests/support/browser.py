"""Waiting for a page to settle in the Playwright tests.

A page is *settled* when its controls answer and nothing on it animates
(``document.getAnimations()`` is empty). Assertions, axe audits and screenshots are made on a
settled page only: axe measures colour contrast as rendered, so a fade still running makes
its result depend on timing. Every wait has a deadline (Playwright's ``timeout``).
"""

from __future__ import annotations

from pathlib import Path

from playwright.sync_api import Browser, BrowserContext, Page, expect

from tests.support.a11y import assert_accessible

SETTLE_TIMEOUT_MS = 30_000
# Playwright's assertions wait 5 s by default, its actions 30 s here (new_page): on a loaded
# 2-core CI machine a page can take longer than 5 s to render (Swagger UI did), so that an
# assertion failed where the page was only slow. Every browser test imports this module.
expect.set_options(timeout=SETTLE_TIMEOUT_MS)

# The labelling page's `#match` says `data-settled` once its pictures are shown, the fade-in
# is over and the controls are enabled (static/js/label.js); a different match id than
# `prev` means a new match.
_MATCH_SETTLED = """prev => { const m = document.getElementById('match');
  return m !== null && m.dataset.settled === 'true' && m.dataset.matchId !== prev
    && document.getAnimations().length === 0; }"""

# Lengthens the labelling page's fade-in and progress bar (static/css/acv.css) from 0.15 s
# and 0.2 s to 1.5 s, so that a test acting on a page still animating fails every time
# instead of now and then.
SLOW_MOTION_CSS = ".match, .progress > div { transition-duration: 1.5s !important; }"


def wait_for_match(page: Page, previous: str | None = None) -> str:
    """Wait until a match (other than ``previous``) is shown and settled; its match id."""
    page.wait_for_function(_MATCH_SETTLED, arg=previous or "", timeout=SETTLE_TIMEOUT_MS)
    match_id = page.get_attribute("#match", "data-match-id")
    assert match_id is not None
    return match_id


def wait_until_still(page: Page) -> None:
    """Wait until nothing on the page animates (a fade, a moving progress bar)."""
    page.wait_for_function("() => document.getAnimations().length === 0", timeout=SETTLE_TIMEOUT_MS)


def slow_motion(page: Page) -> None:
    """Make the labelling page's transitions on the pages ``page`` loads from now on last 1.5 s."""
    # The pages' policy refuses inline <style> elements; a constructed style sheet adopted
    # by the document is not an inline style, so the policy lets it apply.
    page.add_init_script(
        script=f"""document.addEventListener('DOMContentLoaded', () => {{
  const sheet = new CSSStyleSheet(); sheet.replaceSync({SLOW_MOTION_CSS!r});
  document.adoptedStyleSheets = [...document.adoptedStyleSheets, sheet]; }});"""
    )


ADMIN_TOKEN = "browser-test-admin-token-0123456789"


CHROMIUM = "/usr/bin/chromium"


CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking"]


PHONE = {"width": 375, "height": 667}


DESKTOP = {"width": 1280, "height": 860}


SCREENS_COPY = Path("/tmp/acv_screens")


def watch_errors(page: Page, errors: list[str]) -> Page:
    """Collect console errors (CSP violations among them) and uncaught script errors."""
    page.on(
        "console",
        lambda m: (
            errors.append(f"{m.text} ({m.location.get('url')})") if m.type == "error" else None
        ),
    )
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    return page


def new_page(browser: Browser, errors: list[str], **context_args) -> tuple[BrowserContext, Page]:
    context = browser.new_context(**context_args)
    context.set_default_timeout(30_000)
    return context, watch_errors(context.new_page(), errors)


def shown(page: Page, side: str) -> int:
    """The candidate id shown on ``side`` (``a`` = left)."""
    return int(page.get_attribute(f"#img-{side}", "alt").removeprefix("candidate "))


def fits_width(page: Page) -> bool:
    return page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")


def in_view(page: Page, selector: str) -> bool:
    box = page.locator(selector).bounding_box()
    return box is not None and box["y"] + box["height"] <= page.viewport_size["height"]


N_CANDIDATES = 6  # 5 matches in 3 rounds (two byes)


def create_study_and_invite(page: Page, base: str) -> tuple[str, str]:
    """Log in by the ``#token=`` link, create a study through the form, invite one person.

    Returns the study page URL and the invite link shown there.
    """
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    assert ADMIN_TOKEN not in page.url and ADMIN_TOKEN not in page.content()
    page.click("text=New study")
    page.wait_for_selector("#sampling")
    assert_accessible(page, "new-study form")
    page.fill("#name", "Browser study")
    page.fill("#n_candidates", str(N_CANDIDATES))
    page.fill("#seed", "7")
    page.click("button:has-text('Create study')")
    expect(page.locator(".grid figure")).to_have_count(N_CANDIDATES, timeout=90_000)
    page.fill("#count", "1")
    page.click("button:has-text('Add participants')")
    invite = page.locator("td.invite input").first.input_value()
    assert invite.startswith(f"{base}/p/")
    return page.url.split("?")[0], invite


def researcher_page(browser: Browser, base: str, errors: list[str]) -> Page:
    """A desktop page logged in as the researcher (by the ``#token=`` link)."""
    _, page = new_page(browser, errors, viewport=DESKTOP)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    return page
