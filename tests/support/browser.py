"""Waiting for a page to settle in the Playwright tests.

A page is *settled* when its controls answer and nothing on it animates
(``document.getAnimations()`` is empty). Assertions, axe audits and screenshots are made on a
settled page only: axe measures colour contrast as rendered, so a fade still running makes
its result depend on timing. Every wait has a deadline (Playwright's ``timeout``).
"""

from __future__ import annotations

from playwright.sync_api import Page, expect

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
