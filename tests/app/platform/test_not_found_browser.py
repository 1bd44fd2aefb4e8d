"""The page a browser gets for a path that does not exist (a mistyped invite link), or for a
form's target opened as a page (``/logout`` takes only a ``POST``), in a real browser on a
desktop and on a phone, audited by axe-core."""

from __future__ import annotations

import pytest
from playwright.sync_api import Browser, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import DESKTOP, PHONE

pytestmark = pytest.mark.browser


@pytest.mark.parametrize(
    ("path", "status", "says"),
    [
        ("/participate/nope", 404, "There is no such page"),
        ("/logout", 405, "This address only takes a form"),
        ("/studies/1/webhooks", 405, "This address only takes a form"),  # a researcher's
    ],
    ids=["missing", "form-target", "researcher-form-target"],
)
@pytest.mark.parametrize("viewport", [DESKTOP, PHONE], ids=["desktop", "phone"])
def test_a_missing_page_is_a_page_that_says_so(
    server, browser: Browser, viewport, path: str, status: int, says: str
) -> None:
    base, _ = server
    context = browser.new_context(viewport=viewport)
    page = context.new_page()
    response = page.goto(f"{base}{path}")
    assert response is not None and response.status == status
    expect(page.locator("main")).to_contain_text(says)
    expect(page.locator("main")).to_contain_text("open it again exactly as you were sent it")
    assert_accessible(page, f"{status} page ({viewport['width']} px)")
    context.close()
