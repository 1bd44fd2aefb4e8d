"""Sharing one's labels in a public dataset (issue 29 §4) in a real browser: the open link's
consent page offers an optional, unticked checkbox, and the instructions page the same
choice (for participants invited by link, who see no consent page), saved and changed at any
time; on a desktop and on a phone. The researcher then downloads the dataset from the study
page, and ``datasets`` loads it. axe-core checks every page added or changed."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.support.a11y import assert_accessible
from tests.support.browser import ADMIN_TOKEN, DESKTOP, PHONE, fits_width, new_page
from tests.support.hf import check_tables, load, unzipped
from tests.support.labelling import label_bracket, wait_until_prepared
from tests.support.server import HTTP_TIMEOUT_S

pytestmark = pytest.mark.browser
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
CONSENT = "We store your choices and your Prolific id, nothing else."


def study_with_link(base: str) -> tuple[int, str, str]:
    """A ready 4-candidate study with an open link that asks consent, and one participant
    invited by link: ``(study id, open link, invite link)``."""
    with httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api:
        study = api.post(
            "/api/studies", json={"name": "Sharing", "env_id": "Hopper-v5", "n_candidates": 4}
        ).json()
        wait_until_prepared(api, study["id"])
        link = api.put(
            f"/api/studies/{study['id']}/crowd",
            json={"enabled": True, "max_participants": 5, "consent_text": CONSENT},
        ).json()["url"]
        invited = api.post(f"/api/studies/{study['id']}/participants").json()["invite_url"]
    return study["id"], link, invited


def save_choice(page: Page, base: str, share: bool) -> None:
    """Tick or untick the instructions page's box and save it; the page shows it stored."""
    page.set_checked("#share", share)
    page.click("#share-save")
    page.wait_for_url(f"{base}/participate#share-form")
    expect(page.locator("#share")).to_be_checked(checked=share)
    stored = "You agreed" if share else "will not be shared"
    expect(page.locator("#share-state")).to_contain_text(stored)


def test_sharing_is_offered_saved_and_exported(
    server, browser: Browser, screens: Path, tmp_path: Path
) -> None:
    base, _ = server
    errors: list[str] = []
    study_id, link, invited = study_with_link(base)

    visitor, p = new_page(browser, errors, viewport=DESKTOP)
    p.goto(f"{link}?PROLIFIC_PID=share-1")
    expect(p.locator("#consent-text")).to_have_text(CONSENT)
    expect(p.locator("#share")).not_to_be_checked()
    assert_accessible(p, "consent page with the sharing choice")
    p.screenshot(path=screens / "share-consent.png")
    p.check("#share")
    p.click("#agree")
    p.wait_for_url(f"{base}/participate")
    expect(p.locator("#share")).to_be_checked()
    assert_accessible(p, "instructions page with the sharing choice")
    save_choice(p, base, False)
    save_choice(p, base, True)
    token = next(c["value"] for c in visitor.cookies() if c["name"] == "acv_participant")

    _, phone = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    phone.goto(invited)
    phone.wait_for_url(f"{base}/participate")
    expect(phone.locator("#share")).not_to_be_checked()
    assert fits_width(phone)
    assert_accessible(phone, "instructions page on a phone")
    save_choice(phone, base, True)
    assert_accessible(phone, "instructions page on a phone, choice saved")
    phone.screenshot(path=screens / "share-instructions-phone.png", full_page=True)
    _, consent = new_page(browser, errors, viewport=PHONE, is_mobile=True, has_touch=True)
    consent.goto(f"{link}?PROLIFIC_PID=share-2")
    expect(consent.locator("#share")).not_to_be_checked()
    assert fits_width(consent)
    assert_accessible(consent, "consent page on a phone")

    with httpx.Client(base_url=base, timeout=HTTP_TIMEOUT_S) as api:
        label_bracket(api, token, lambda m: m["left"])
        listed = api.get(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    assert [p["share_consent"] for p in listed] == [True, True]

    _, page = new_page(browser, errors, viewport=DESKTOP, accept_downloads=True)
    page.goto(f"{base}/login#token={ADMIN_TOKEN}")
    page.wait_for_url(f"{base}/studies")
    page.goto(f"{base}/studies/{study_id}#quality")
    expect(page.locator("#dataset-export")).to_contain_text("of the 2 participants who agreed")
    assert_accessible(page, "study page with the dataset download")
    page.locator("#dataset-export").screenshot(path=screens / "share-study-download.png")
    with page.expect_download() as download:
        page.click("#dataset-export a")
    zipped = download.value.path().read_bytes()
    tables = load(unzipped(zipped, tmp_path / "zip"), tmp_path / "cache")
    check_tables(tables, n_candidates=4)
    assert tables["labels"].num_rows == 3 and tables["participants"].num_rows == 2
    assert errors == []
