"""A researcher's form refused on the study and survey pages (webhooks, gold items, invites)
shows its page again, with the form as typed and what was wrong beside it, and stores nothing;
it used to be a bare error page that lost what was typed (``app.http.forms``)."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.support.surveys import paper_body, participant_trees
from tests.support.web import ADMIN, csrf_token, logged_in, shown_again

#: form name -> (path under the study page, the fields typed, the reason's words, the API
#: listing that must not grow, {input id: its field}).
STUDY_FORMS: dict[str, tuple[str, dict[str, str], str, str, dict[str, str]]] = {
    "webhook": (
        "webhooks",
        {"url": "https://10.0.0.1/hook"},
        "loopback",
        "/api/webhooks?study_id={id}",
        {"webhook-url": "url"},
    ),
    "gold": (
        "gold",
        {"kind": "instructed", "a": "3", "b": "3", "answer": "3"},
        "two different candidates",
        "/api/studies/{id}/gold",
        {"gold-a": "a", "gold-b": "b", "gold-answer": "answer"},
    ),
    "invite": (
        "participants",
        {"count": "1_0", "name": "lab session 7"},
        "whole number",
        "/api/studies/{id}/participants",
        {"count": "count", "invite-name": "name"},
    ),
}


def _count(client: TestClient, listing: str) -> int:
    return len(client.get(listing, headers=ADMIN).json())


@pytest.mark.parametrize("form", STUDY_FORMS)
def test_a_refused_study_form_comes_back_as_typed(
    client: TestClient, study: dict[str, Any], form: str
) -> None:
    path, typed, says, listing, inputs = STUDY_FORMS[form]
    page, study_path = logged_in(client), f"/studies/{study['id']}"
    listing = listing.format(id=study["id"])
    before = _count(client, listing)
    token = csrf_token(page, study_path)
    refused = page.post(f"{study_path}/{path}", data={"csrf_token": token, **typed})
    assert refused.status_code == 422, refused.text
    assert f"<title>{study['name']}" in refused.text and says in refused.text
    shown_again(refused.text, form, typed, inputs)
    assert _count(client, listing) == before
    if form == "gold":  # the kind chosen stays chosen
        assert '<option value="instructed" selected>' in refused.text
    # The page without a refusal marks no field.
    assert 'class="field-error"' not in page.get(study_path).text


def test_a_refused_survey_webhook_comes_back_as_typed(
    client: TestClient, study: dict[str, Any]
) -> None:
    trees = participant_trees(client, study["id"])
    survey = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN).json()
    page, path = logged_in(client), f"/surveys/{survey['id']}"
    typed = {"url": "ftp://127.0.0.1/hook"}
    refused = page.post(f"{path}/webhooks", data={"csrf_token": csrf_token(page, path), **typed})
    assert refused.status_code == 422 and "<title>Survey: " in refused.text, refused.text
    shown_again(refused.text, "webhook", typed, {"webhook-url": "url"})
    assert _count(client, f"/api/webhooks?survey_id={survey['id']}") == 0
