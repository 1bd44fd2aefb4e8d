"""A survey respondent whose last screens are submitted at the same moment (two tabs, an API
client) is marked finished, with the open link's completion code where one applies (issue 24,
F2); migration 0010 repairs the respondents an earlier version left stuck, and 0011 marks
which study participants came through an open link (F5). On SQLite and PostgreSQL."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy import text

from app.db import make_engine, upgrade
from app.models import SurveyRespondent
from app.recruiting import service as recruiting
from app.surveys import answers as survey_answers
from app.surveys import crowd as survey_crowd
from app.surveys import respond as survey_respond
from app.surveys.answers import AnswerIn
from tests.support.postgres import BACKENDS, empty_database
from tests.support.surveys import invite, paper_body, participant_trees
from tests.support.web import ADMIN

RESPONDENTS = 30


@pytest.fixture(scope="module")
def survey(client: TestClient, study: dict[str, Any]) -> dict[str, Any]:
    """A paper survey (one stimulus and the attention check: two screens) with an open link
    that gives a completion code."""
    body = paper_body(*participant_trees(client, study["id"]))
    made = client.post("/api/surveys", json=body, headers=ADMIN)
    assert made.status_code == 201, made.text
    link = {"enabled": True, "max_participants": 100, "completion_code": "F2DONE"}
    put = client.put(f"/api/surveys/{made.json()['id']}/crowd", json=link, headers=ADMIN)
    assert put.status_code == 200, put.text
    return made.json()


def _people(client: TestClient, survey_id: int) -> list[int]:
    """Half invited, half through the open link; every one's screens planned."""
    invited = [r.id for r in invite(client, survey_id, RESPONDENTS // 2)]
    with client.app.state.runtime.sessions() as session:
        link = recruiting.settings(session, survey_crowd.LINK, survey_id)
        assert link is not None
        crowd = [
            recruiting.join(session, survey_crowd.LINK, link=link, ids={}).id
            for _ in range(RESPONDENTS - len(invited))
        ]
        for rid in invited + crowd:
            survey_respond.start(session, respondent=session.get_one(SurveyRespondent, rid))
    return invited + crowd


def test_screens_submitted_at_once_finish_the_respondent(client, survey, monkeypatch) -> None:
    """Both screens of each respondent are submitted by two threads that have each read the
    screen plan before either writes (a barrier after ``start``): the one decided last must
    see the other's stored screen and mark the respondent finished."""
    people = _people(client, survey["id"])
    barriers = {rid: threading.Barrier(2, timeout=60) for rid in people}
    planned = survey_respond.start

    def start_then_meet(session, *, respondent):
        plan = planned(session, respondent=respondent)
        barriers[respondent.id].wait()  # both submits of this respondent hold a plan
        return plan

    monkeypatch.setattr(survey_respond, "start", start_then_meet)

    def submit(rid: int, position: int) -> bool:
        with client.app.state.runtime.sessions() as session:
            person = session.get_one(SurveyRespondent, rid)
            screen = survey_respond.screens_of(session, respondent_id=rid)[position - 1]
            survey_row = survey_respond.get_survey(session, survey_id=person.survey_id)
            stimulus = session.get_one(survey_respond.SurveyStimulus, screen.stimulus_id)
            answers = {
                q["key"]: AnswerIn((q["options"] or ["why"])[0], 3 if q["confidence"] else None)
                for q in survey_respond.questions_for(survey_row, stimulus)
            }
            return survey_answers.submit(
                session, respondent=person, position=position, answers=answers, screen_ms=5
            )

    jobs = [(rid, position) for rid in people for position in (1, 2)]
    with ThreadPoolExecutor(max_workers=8) as pool:  # a respondent's two jobs run together
        stored = list(pool.map(lambda job: submit(*job), jobs))
    assert all(stored)
    with client.app.state.runtime.sessions() as session:
        for rid in people:
            person = session.get_one(SurveyRespondent, rid)
            assert survey_respond.progress(session, respondent_id=rid) == (2, 2)
            assert person.finished_at is not None, f"respondent {rid} left unfinished"
            link = recruiting.completion(session, survey_crowd.LINK, member=person)
            assert (link.code if link else None) == ("F2DONE" if person.via_link else None)
    listed = client.get(f"/api/surveys/{survey['id']}/respondents", headers=ADMIN).json()
    assert sum(r["finished"] for r in listed) == RESPONDENTS


@pytest.mark.parametrize("backend", BACKENDS)
def test_migration_0010_finishes_stuck_respondents_and_keeps_every_row(
    request, tmp_path, backend: str
) -> None:
    url = empty_database(request, tmp_path, backend)
    upgrade(url, "0009")
    done, early = "2026-11-20 12:00:00", "2026-11-20 11:00:00"
    engine = make_engine(url)
    with engine.begin() as conn:
        for statement in (
            "INSERT INTO surveys (id, name, intro, template, questions, highlights, assignment, "
            "exclusion_rule, seed, rr_counter, created_at) VALUES (1, 's', '', 'paper', '[]', "
            "false, 'all', 'none', 0, 0, CURRENT_TIMESTAMP)",
            "INSERT INTO survey_stimuli (id, survey_id, position, label, attention_check, trees, "
            "expected) VALUES (1, 1, 1, 'a', false, '[]', '{}'), "
            "(2, 1, 2, 'b', false, '[]', '{}')",
            # 1: stuck (both screens answered, not finished); 2: half way; 3: finished.
            "INSERT INTO survey_respondents (id, survey_id, token, token_hash, created_at, "
            "started_at, finished_at, via_link) VALUES "
            "(1, 1, 't1', 'h1', CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, NULL, true), "
            "(2, 1, 't2', 'h2', CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, NULL, false), "
            "(3, 1, 't3', 'h3', CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, :done, false), "
            "(4, 1, 't4', 'h4', CURRENT_TIMESTAMP, NULL, NULL, false)",
            "INSERT INTO survey_screens (respondent_id, position, stimulus_id, tree1_left, "
            "answered_at) VALUES (1, 1, 1, true, :early), (1, 2, 2, false, :done), "
            "(2, 1, 1, true, :done), (2, 2, 2, true, NULL), "
            "(3, 1, 1, true, :early), (3, 2, 2, true, :early)",
        ):
            conn.execute(text(statement), {"done": done, "early": early})
    engine.dispose()
    upgrade(url, "0010")  # the revision under test (0017 moves the columns read here)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(
                text("SELECT id, finished_at FROM survey_respondents ORDER BY id")
            ).all()
            screens = conn.execute(text("SELECT COUNT(*) FROM survey_screens")).scalar()
            last = conn.execute(
                text(
                    "SELECT answered_at FROM survey_screens"
                    " WHERE respondent_id = 1 AND position = 2"
                )
            ).scalar()
    finally:
        engine.dispose()
    assert [r[0] for r in rows] == [1, 2, 3, 4] and screens == 6
    finished = {rid: at is not None for rid, at in rows}
    assert finished == {1: True, 2: False, 3: True, 4: False}
    assert rows[0][1] == last  # finished when they answered their last screen


@pytest.mark.parametrize("backend", BACKENDS)
def test_migration_0011_marks_existing_crowd_participants(request, tmp_path, backend) -> None:
    """Participants of a study with an open link keep getting its code (they may be crowd
    workers part way through); those of a study without one never had a code to get."""
    url = empty_database(request, tmp_path, backend)
    upgrade(url, "0010")
    engine = make_engine(url)
    with engine.begin() as conn:
        for statement in (
            "INSERT INTO studies (id, name, env_id, n_candidates, p, seed, sampling, "
            "instructions, status, created_at) VALUES (1, 's', 'Hopper-v5', 2, 0.9, 0, "
            "'uniform', '', 'ready', CURRENT_TIMESTAMP), (2, 't', 'Hopper-v5', 2, 0.9, 0, "
            "'uniform', '', 'ready', CURRENT_TIMESTAMP)",
            "INSERT INTO crowd_settings (study_id, slug, enabled, max_participants, joined, "
            "declines, external_params, consistency_check, speed_threshold_ms) VALUES "
            "(1, 'slug', true, 5, 1, 0, '[\"PROLIFIC_PID\"]', false, 800)",
            "INSERT INTO participants (id, study_id, token, token_hash, created_at) VALUES "
            "(1, 1, 't1', 'h1', CURRENT_TIMESTAMP), (2, 2, 't2', 'h2', CURRENT_TIMESTAMP)",
        ):
            conn.execute(text(statement))
    engine.dispose()
    upgrade(url, "0011")  # the revision under test (0017 moves the columns read here)
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            rows = conn.execute(text("SELECT id, via_link FROM participants ORDER BY id")).all()
    finally:
        engine.dispose()
    assert [(pid, bool(via)) for pid, via in rows] == [(1, True), (2, False)]
