"""Revision 0017 (one members table, one open-links table) keeps every person, label, gold
answer, respondent, answer and link, and every export, on SQLite and PostgreSQL.

The database is filled through the app at head, exported, taken down to 0016 (the previous
head's layout, where a respondent is given an id that a participant also has, as two tables
allowed), and upgraded again: the counts, the exports (``labels.csv``, ``answers.csv``, the
dataset's files) and the listings are the same, byte for byte, and a new member of each kind
can join afterwards.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fastapi.testclient import TestClient
from sqlalchemy import text

from app.db import downgrade, make_engine, upgrade
from app.models import token_digest
from tests.support.crowd import configure, join, joined_player, visit
from tests.support.hf import unzipped
from tests.support.runs import run_app
from tests.support.studies import Player, new_study
from tests.support.surveys import Respondent, invite, paper_answers, paper_body
from tests.support.web import ADMIN

#: The tables of people's rows that both layouts have.
KEPT = (
    "participants",
    "matches",
    "labels",
    "gold_answers",
    "survey_respondents",
    "survey_screens",
    "survey_answers",
)
#: The links' tables at 0016.
OLD_LINKS = ("crowd_settings", "survey_crowd_settings")


def _invited_player(client: TestClient, study_id: int, *, share: bool) -> Player:
    body = client.post(f"/api/studies/{study_id}/participants", headers=ADMIN).json()
    player = Player(client, body["id"], body["token"], body["invite_url"])
    shared = client.put(
        "/api/participants/me/share-consent", json={"share": share}, headers=player.headers
    )
    assert shared.status_code == 200, shared.text
    return player


def _fill(client: TestClient) -> dict[str, int]:
    """A study with a gold item, an open link, two finished participants (one sharing) and one
    who joined through the link part way; a survey on their trees with an open link, one
    invited respondent who answered everything and one who joined through the link."""
    study = new_study(client)["id"]
    gold = {"kind": "pair", "a": 0, "b": 1, "answer": 1}
    assert client.post(f"/api/studies/{study}/gold", json=gold, headers=ADMIN).status_code == 201
    link = configure(client, study, completion_code="DONE-1")
    players = [_invited_player(client, study, share=share) for share in (True, False)]
    players[0].play()
    players[1].play(lambda m: m["b"]["candidate_id"])
    crowd = joined_player(client, *visit(client, link, "?PROLIFIC_PID=w1&SESSION_ID=s1"))
    match = crowd.next_match()
    assert match is not None
    assert crowd.label(match["match_id"], match["a"]["candidate_id"]).status_code == 201
    trees = [{"kind": "participant", "participant_id": p.id} for p in players]
    survey = client.post("/api/surveys", json=paper_body(*trees), headers=ADMIN).json()["id"]
    hook = {"url": "http://127.0.0.1:9/hook", "survey_id": survey}
    assert client.post("/api/webhooks", json=hook, headers=ADMIN).status_code == 201
    options = {"enabled": True, "max_participants": 5, "completion_code": "DONE-2"}
    survey_link = client.put(f"/api/surveys/{survey}/crowd", json=options, headers=ADMIN).json()
    [respondent] = invite(client, survey)
    while (screen := respondent.screen()) is not None:
        assert respondent.answer(screen["position"], paper_answers(screen)).status_code == 201
    visitor = TestClient(client.app, follow_redirects=False)
    joined = join(visitor, f"/q/{survey_link['slug']}?PROLIFIC_PID=r1")
    assert joined.status_code == 303, joined.text
    return {"study": study, "survey": survey, "first_participant": players[0].id}


def _exports(client: TestClient, ids: dict[str, int], into: Path) -> dict[str, bytes]:
    """Every export and listing that names a member, as bytes."""
    study, survey = ids["study"], ids["survey"]
    paths = {
        "labels.csv": f"/api/studies/{study}/labels.csv?include_excluded=true",
        "answers.csv": f"/api/surveys/{survey}/answers.csv",
        "participants": f"/api/studies/{study}/participants",
        "respondents": f"/api/surveys/{survey}/respondents",
        "study link": f"/api/studies/{study}/crowd",
        "survey link": f"/api/surveys/{survey}/crowd",
    }
    found = {}
    for name, path in paths.items():
        response = client.get(path, headers=ADMIN)
        assert response.status_code == 200, (name, response.text)
        found[name] = response.content
    dataset = client.get(f"/api/studies/{study}/export/dataset.zip", headers=ADMIN)
    assert dataset.status_code == 200, dataset.text
    folder = unzipped(dataset.content, into)
    for file in sorted(folder.rglob("*")):
        if file.is_file():
            found[f"dataset/{file.relative_to(folder)}"] = file.read_bytes()
    return found


def _counts(url: str, tables: tuple[str, ...]) -> dict[str, int]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return {t: conn.execute(text(f"SELECT count(*) FROM {t}")).scalar_one() for t in tables}
    finally:
        engine.dispose()


def _respondent_beside_a_participant(url: str, *, survey_id: int, participant_id: int) -> None:
    """At 0016, an invited respondent whose id is also a participant's (each table had its
    own ids then)."""
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            conn.execute(
                text(
                    "INSERT INTO survey_respondents (id, survey_id, token, token_hash, "
                    "created_at, via_link, share_consent) VALUES (:id, :survey, 'twin-token', "
                    ":hash, CURRENT_TIMESTAMP, false, false)"
                ),
                {"id": participant_id, "survey": survey_id, "hash": token_digest("twin-token")},
            )
    finally:
        engine.dispose()


def _largest_member_id(url: str) -> int:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return conn.execute(text("SELECT max(id) FROM members")).scalar_one()
    finally:
        engine.dispose()


def test_the_members_revision_keeps_every_row_and_export(settings, tmp_path: Path) -> None:
    url = settings.sqlalchemy_url
    with run_app(settings, worker=False) as client:
        ids = _fill(client)
        before = _exports(client, ids, tmp_path / "before")
    downgrade(url, "0016")
    _respondent_beside_a_participant(
        url, survey_id=ids["survey"], participant_id=ids["first_participant"]
    )
    counts, links = _counts(url, KEPT), _counts(url, OLD_LINKS)
    assert all(counts.values()) and links == {t: 1 for t in OLD_LINKS}, (counts, links)
    upgrade(url)
    assert _counts(url, KEPT) == counts
    merged = _counts(url, ("members", "open_links"))
    assert merged == {
        "members": counts["participants"] + counts["survey_respondents"],
        "open_links": 2,
    }
    with run_app(settings, worker=False) as client:
        after = _exports(client, ids, tmp_path / "after")
        _check_new_members(client, ids, url)
    twin = _listed(after["respondents"])[ids["first_participant"]]
    assert twin["token"] == "twin-token"  # shown under the id it had
    assert {k: v for k, v in after.items() if k != "respondents"} == {
        k: v for k, v in before.items() if k != "respondents"
    }
    assert {i: r for i, r in _listed(after["respondents"]).items() if i != twin["id"]} == _listed(
        before["respondents"]
    )


def _listed(body: bytes) -> dict[int, Any]:
    return {r["id"]: r for r in json.loads(body)}


def _check_new_members(client: TestClient, ids: dict[str, int], url: str) -> None:
    """A participant and a respondent invited after the upgrade get ids above every member's;
    the renumbered twin's invite token still opens their survey."""
    largest = _largest_member_id(url)
    body = client.post(f"/api/studies/{ids['study']}/participants", headers=ADMIN).json()
    [fresh] = invite(client, ids["survey"])
    assert body["id"] > largest and fresh.id > body["id"]
    twin = Respondent(client, ids["first_participant"], "twin-token", "")
    while (screen := twin.screen()) is not None:
        assert twin.answer(screen["position"], paper_answers(screen)).status_code == 201
    assert _finished_payloads(url) == [twin.id]  # the id they had, in the webhook's payload


def _finished_payloads(url: str) -> list[int]:
    """The respondent ids of the ``respondent.finished`` events written since the upgrade."""
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            events = conn.execute(
                text(
                    "SELECT payload FROM webhook_events "
                    "WHERE type = 'respondent.finished' ORDER BY id"
                )
            ).scalars()
            payloads = [json.loads(p) if isinstance(p, str) else p for p in events]
    finally:
        engine.dispose()
    return [p["data"]["respondent_id"] for p in payloads][1:]  # the first: before the upgrade
