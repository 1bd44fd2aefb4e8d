"""An open link without consent text, in a real browser: the visitor gets a start page
(fetching the link takes no seat), on a desktop and on a phone, audited by axe-core; pressing
Start makes them a participant."""

from __future__ import annotations

import httpx
import pytest
from playwright.sync_api import Browser, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, DESKTOP, PHONE, new_page
from tests.support.labelling import wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S

pytestmark = pytest.mark.browser


def _open_study_link(base: str) -> tuple[str, str]:
    """A ready study with an open link and no consent text: its link and settings path."""
    headers = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
    with httpx.Client(base_url=base, headers=headers, timeout=HTTP_TIMEOUT_S) as api:
        body = {"name": "Start page", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 5}
        study_id = api.post("/api/studies", json=body).json()["id"]
        wait_until_prepared(api, study_id)
        settings = f"/api/studies/{study_id}/crowd"
        link = api.put(settings, json={"enabled": True, "max_participants": 5}).json()["url"]
    return link, settings


def _joined(base: str, settings: str) -> int:
    headers = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
    with httpx.Client(base_url=base, headers=headers, timeout=HTTP_TIMEOUT_S) as api:
        return int(api.get(settings).json()["joined"])


def test_a_link_without_consent_starts_with_a_button(server, browser: Browser) -> None:
    base, _ = server
    link, settings = _open_study_link(base)
    errors: list[str] = []
    for name, viewport in (("desktop", DESKTOP), ("phone", PHONE)):
        context, page = new_page(browser, errors, viewport=viewport, has_touch=True)
        page.goto(f"{link}?PROLIFIC_PID=start-{name}")
        expect(page.locator("h1")).to_have_text("Welcome")
        expect(page.locator("#start")).to_be_visible()
        assert_accessible(page, f"start page ({name})")
        context.close()
    assert _joined(base, settings) == 0  # two visits, no seat taken

    _, page = new_page(browser, errors, viewport=PHONE, has_touch=True)
    page.goto(f"{link}?PROLIFIC_PID=start-phone")
    page.tap("#start")
    page.wait_for_url(f"{base}/participate")
    assert _joined(base, settings) == 1
    assert errors == []
