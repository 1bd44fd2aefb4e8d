"""``/docs`` (Swagger UI, "API" in the menu) in a real browser, audited by axe-core.

ACV fixes what its own configuration controls: the page's language and, in
``static/css/swagger-overrides.css``, colours that fail contrast. What remains is Swagger UI's
own markup, listed in ``docs/accessibility.md`` and allowed here by rule id and target, so that
anything new still fails.
"""

from __future__ import annotations

import pytest
from axe_playwright_python.sync_playwright import Axe
from playwright.sync_api import Browser, expect

from tests.support.browser import DESKTOP, new_page

pytestmark = pytest.mark.browser
# Swagger UI's own markup, not ACV's (docs/accessibility.md): each operation's summary is a
# button that holds the copy-path button.
UPSTREAM = {("nested-interactive", ".opblock-summary-control")}


@pytest.mark.parametrize("scheme", ["light", "dark"])
def test_docs_page(server, browser: Browser, scheme) -> None:
    base, _ = server
    errors: list[str] = []
    context, page = new_page(browser, errors, viewport=DESKTOP, color_scheme=scheme)
    page.goto(f"{base}/docs")
    expect(page.locator(".opblock-summary").first).to_be_visible()
    assert page.evaluate("document.documentElement.lang") == "en"
    page.locator(".opblock-summary").first.click()  # one operation opened
    expect(page.locator(".opblock-body").first).to_be_visible()
    response = Axe().run(page).response
    found = sorted(  # (rule, the failing element's last selector step)
        {
            (v["id"], str(n["target"][-1]).split(" > ")[-1])
            for v in response["violations"]
            if v["impact"] in ("serious", "critical")
            for n in v["nodes"]
        }
    )
    context.close()
    assert set(found) - UPSTREAM == set(), found
    assert errors == []
