"""A dataset that others can load (issue 29 §4), through the REST API and the participants'
pages, on SQLite and PostgreSQL: sharing is each participant's optional choice (off by
default; the consent page's checkbox, the instructions page, ``PUT
/api/participants/me/share-consent``), and ``GET /api/studies/{id}/export/dataset.zip`` holds
only those who agreed and are not excluded, under stable pseudonyms, in a folder that
``datasets`` loads. Bad input is a 4xx with a clear detail and changes nothing."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.core.auth import PARTICIPANT_COOKIE
from tests.support.crowd import configure, visit
from tests.support.hf import CONFIGS, SHARE, card, check_tables, consent, export, load, unzipped
from tests.support.web import ADMIN, csrf_token


def shares(client: TestClient, study_id: int) -> dict[int, bool]:
    listed = client.get(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    return {p["id"]: p["share_consent"] for p in listed}


def test_share_consent_is_off_by_default_strict_and_revocable(client, study, invite) -> None:
    player = invite()
    assert shares(client, study["id"])[player.id] is False
    for bad in ({"share": "true"}, {"share": 1}, {"share": None}, {}, {"share": True, "x": 1}):
        response = client.put(SHARE, json=bad, headers=player.headers)
        assert response.status_code == 422, (bad, response.text)
    assert client.put(SHARE, json={"share": True}).status_code == 401
    assert shares(client, study["id"])[player.id] is False  # nothing changed
    assert consent(player, True).json() == {"share": True}
    assert shares(client, study["id"])[player.id] is True
    assert consent(player, False).json() == {"share": False}
    assert shares(client, study["id"])[player.id] is False


def test_no_one_to_share_is_a_409_with_a_clear_detail(client, make_study, invite) -> None:
    study_id = make_study()["id"]
    player = invite(study_id)
    player.play()
    refused = export(client, study_id)
    assert refused.status_code == 409
    assert "no participant who agreed to share" in refused.json()["detail"]
    consent(player, True)
    excluded = client.put(
        f"/api/participants/{player.id}/exclusion", json={"excluded": True}, headers=ADMIN
    )
    assert excluded.status_code == 200
    assert export(client, study_id).status_code == 409  # the excluded are never shared
    fresh = invite(study_id)
    consent(fresh, True)
    unlabelled = export(client, study_id)
    assert unlabelled.status_code == 409 and "labelled a pair yet" in unlabelled.json()["detail"]
    assert export(client, 999_999).status_code == 404
    url = f"/api/studies/{study_id}/export/dataset.zip"
    assert client.get(url).status_code == 401  # the researcher's alone
    assert client.get(url, headers=player.headers).status_code in (401, 403)
    assert export(client, study_id, "?license=Not%20a%20licence").status_code == 422


def test_the_dataset_loads_with_only_those_who_agreed(
    client, make_study, invite, tmp_path: Path
) -> None:
    study_id = make_study(n_candidates=5)["id"]
    agreed, declined, excluded, started = (invite(study_id) for _ in range(4))
    for player in (agreed, declined, excluded):
        assert player.play() == 4
    for player in (agreed, excluded, started):
        consent(player, True)
    match = started.next_match()
    assert started.label(match["match_id"], match["b"]["candidate_id"]).status_code == 201
    client.put(f"/api/participants/{excluded.id}/exclusion", json={"excluded": True}, headers=ADMIN)

    response = export(client, study_id, "?license=mit")
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "application/zip"
    folder = unzipped(response.content, tmp_path / "zip")
    assert folder.name == f"study-{study_id}-dataset"
    tables = load(folder, tmp_path / "cache")
    check_tables(tables, n_candidates=5)
    people = tables["participants"].to_list()
    assert sorted(p["labels"] for p in people) == [1, 4]
    assert sorted(p["finished"] for p in people) == [False, True]
    assert tables["labels"].num_rows == 5 and tables["trees"].num_rows == 1
    ids = {str(p.id) for p in (agreed, declined, excluded, started)}
    assert not ids & {p["participant"] for p in people}
    meta = card(folder)
    assert meta["license"] == "mit"
    assert [c["config_name"] for c in meta["configs"]] == list(CONFIGS)
    assert "Verma" in (folder / "README.md").read_text()

    again = unzipped(export(client, study_id, "?license=mit").content, tmp_path / "again")
    repeat = load(again, tmp_path / "cache2")["participants"]["participant"]
    assert sorted(repeat) == sorted(p["participant"] for p in people)  # stable pseudonyms


def test_the_consent_page_checkbox_is_optional_and_unticked(client, make_study) -> None:
    study_id = make_study()["id"]
    link = configure(client, study_id, consent_text="We store your choices.")
    made = {}
    for share in (True, False):
        browser, page = visit(client, link, f"?PROLIFIC_PID=share-{share}")
        assert 'name="share" id="share"' in page.text and "checked" not in page.text
        csrf = page.text.split('name="csrf_token" value="')[1].split('"')[0]
        form = {"csrf_token": csrf, "decision": "agree", "PROLIFIC_PID": f"share-{share}"}
        joined = browser.post(f"/s/{link['slug']}", data=form | ({"share": "on"} if share else {}))
        assert joined.status_code == 303, joined.text
        token = browser.cookies[PARTICIPANT_COOKIE]
        me = client.get("/api/participants/me", headers={"Authorization": f"Bearer {token}"})
        made[me.json()["id"]] = share
    assert {pid: shares(client, study_id)[pid] for pid in made} == made


def test_the_instructions_page_records_the_choice(client, study, invite) -> None:
    player = invite()
    page = TestClient(client.app, follow_redirects=False)
    assert page.get(player.invite_url).status_code in (303, 307)
    csrf = csrf_token(page, "/participate")
    assert 'id="share"' in page.get("/participate").text
    assert page.post("/participate/share", data={"share": "on"}).status_code == 403  # no CSRF
    assert shares(client, study["id"])[player.id] is False
    saved = page.post("/participate/share", data={"csrf_token": csrf, "share": "on"})
    assert saved.status_code == 303 and saved.headers["location"] == "/participate#share-form"
    assert shares(client, study["id"])[player.id] is True
    assert "You agreed" in page.get("/participate").text
    page.post("/participate/share", data={"csrf_token": csrf})  # unticked: withdrawn
    assert shares(client, study["id"])[player.id] is False


@pytest.mark.parametrize("body", [{"share": "on"}, []])
def test_share_consent_refuses_other_bodies(client, invite, body: Any) -> None:
    player = invite()
    response = client.put(SHARE, json=body, headers=player.headers)
    assert response.status_code == 422 and response.json()["detail"]
