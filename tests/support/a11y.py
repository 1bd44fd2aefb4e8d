"""Accessibility checks inside the Playwright tests: axe-core (WCAG 2.1 AA rules).

axe-core is the npm package's build that ``axe-playwright-python`` ships; it runs inside the
page through Playwright's evaluate, which the pages' Content Security Policy does not block.
"""

from __future__ import annotations

from axe_playwright_python.sync_playwright import Axe
from playwright.sync_api import Page


def assert_accessible(page: Page, what: str = "page") -> None:
    """axe-core on the page as it is now: no serious or critical violation."""
    response = Axe().run(page).response
    assert response["testEngine"]["name"] == "axe-core"  # it ran, inside this page
    bad = [
        f"{v['id']} ({v['impact']}): {v['help']} at {[n['target'] for n in v['nodes']][:3]}"
        for v in response["violations"]
        if v["impact"] in ("serious", "critical")
    ]
    assert bad == [], f"{what}: {bad}"
