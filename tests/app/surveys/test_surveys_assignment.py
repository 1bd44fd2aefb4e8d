"""Randomisation and counterbalancing: each respondent's order and left/right placement come
from a generator seeded by the survey's seed and their id (stored, and recomputable); the
placement is balanced (seeded check); round-robin assignment hands out stimuli in turn, also
to respondents starting at the same moment (SQLite and PostgreSQL)."""

from __future__ import annotations

from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from scipy.stats import binomtest

from app.models import Survey, SurveyScreen
from app.surveys.respond import plan_screens, respondent_rng
from tests.support.surveys import finished, invite, paper_answers
from tests.support.web import ADMIN


@pytest.fixture(scope="module")
def sources(client: TestClient, study: dict[str, Any]) -> list[dict[str, Any]]:
    return [
        {"kind": "participant", "participant_id": finished(client, study["id"], side)}
        for side in ("a", "b")
    ]


def three_stimuli(client: TestClient, sources: list[dict[str, Any]], **extra: Any) -> int:
    one, two = sources
    body = {
        "name": "Counterbalanced",
        "stimuli": [
            {"label": "A", "tree1": one, "tree2": two},
            {"label": "B", "tree1": two, "tree2": one},
            {"label": "C", "tree1": one, "tree2": two},
        ],
        "attention_check": {"question": "q1", "expected": "same"},
    } | extra
    response = client.post("/api/surveys", json=body, headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()["id"]


def test_plans_are_seeded_and_balanced() -> None:
    """Seeded check: over 2000 respondents of 3 stimuli and an attention check, Tree 1 is on
    the left of about half the screens, and every stimulus is about equally often first."""
    lefts, firsts, screens = 0, Counter(), 0
    for respondent in range(2000):
        plan = plan_screens(
            np.random.default_rng([7, respondent]), stimulus_ids=[1, 2, 3], attention_id=9
        )
        assert sorted(sid for sid, _ in plan) == [1, 2, 3, 9]
        lefts += sum(left for _, left in plan)
        screens += len(plan)
        firsts[plan[0][0]] += 1
    assert binomtest(lefts, screens, 0.5).pvalue > 0.01
    assert abs(lefts / screens - 0.5) < 0.02
    assert all(abs(firsts[s] / 2000 - 0.25) < 0.04 for s in (1, 2, 3, 9))
    again = plan_screens(np.random.default_rng([7, 5]), stimulus_ids=[1, 2, 3], attention_id=9)
    assert again == plan_screens(
        np.random.default_rng([7, 5]), stimulus_ids=[1, 2, 3], attention_id=9
    )


def test_stored_plan_is_the_seeded_one(client, sources) -> None:
    survey_id = three_stimuli(client, sources, seed=11)
    people = invite(client, survey_id, count=6)
    for person in people:
        person.screen()
    with client.app.state.runtime.sessions() as session:
        survey = session.get(Survey, survey_id)
        stimulus_ids = sorted(
            {
                s.stimulus_id
                for s in session.query(SurveyScreen).filter(
                    SurveyScreen.respondent_id == people[0].id
                )
            }
        )
        for person in people:
            stored = [
                (s.stimulus_id, s.tree1_left)
                for s in session.query(SurveyScreen)
                .filter(SurveyScreen.respondent_id == person.id)
                .order_by(SurveyScreen.position)
            ]
            expected = plan_screens(
                respondent_rng(survey, person.id),
                stimulus_ids=stimulus_ids[:3],
                attention_id=stimulus_ids[3],
            )
            assert stored == expected


def test_screens_show_the_stored_side(client, sources) -> None:
    survey_id = three_stimuli(client, sources, seed=3)
    [person] = invite(client, survey_id)
    seen = []
    while (screen := person.screen()) is not None:
        seen.append(screen["left"]["name"])
        assert (
            person.answer(screen["position"], paper_answers(screen, q1="same")).status_code == 201
        )
    with client.app.state.runtime.sessions() as session:
        stored = [
            ("Tree 1" if s.tree1_left else "Tree 2")
            for s in session.query(SurveyScreen)
            .filter(SurveyScreen.respondent_id == person.id)
            .order_by(SurveyScreen.position)
        ]
    assert seen == stored and len(seen) == 4


def test_round_robin_hands_out_stimuli_in_turn(client, sources) -> None:
    survey_id = three_stimuli(client, sources, assignment="round_robin")
    people = invite(client, survey_id, count=7)
    for person in people:
        screens = []
        while (screen := person.screen()) is not None:
            screens.append(screen)
            assert (
                person.answer(screen["position"], paper_answers(screen, q1="same")).status_code
                == 201
            )
        assert len(screens) == 2  # one stimulus and the attention check
    assigned = [
        r["stimulus_id"]
        for r in client.get(f"/api/surveys/{survey_id}/respondents", headers=ADMIN).json()
    ]
    first_three = assigned[:3]
    assert len(set(first_three)) == 3
    assert assigned == [first_three[i % 3] for i in range(7)]


def test_round_robin_is_atomic_under_concurrency(client, sources) -> None:
    """24 respondents open the survey at once (8 threads): every counter value is handed out
    once, so the three stimuli get exactly 8 respondents each."""
    survey_id = three_stimuli(client, sources, assignment="round_robin")
    people = invite(client, survey_id, count=24)
    with ThreadPoolExecutor(max_workers=8) as pool:
        list(pool.map(lambda p: p.screen(), people))
    respondents = client.get(f"/api/surveys/{survey_id}/respondents", headers=ADMIN).json()
    assert sorted(Counter(r["stimulus_id"] for r in respondents).values()) == [8, 8, 8]
    with client.app.state.runtime.sessions() as session:
        assert session.get(Survey, survey_id).rr_counter == 24


def test_one_respondent_starting_twice_at_once_gets_one_plan(client, sources) -> None:
    survey_id = three_stimuli(client, sources, assignment="round_robin")
    [person] = invite(client, survey_id)
    with ThreadPoolExecutor(max_workers=6) as pool:
        screens = list(pool.map(lambda _: person.screen(), range(6)))
    assert all(s == screens[0] for s in screens)
    with client.app.state.runtime.sessions() as session:
        assert session.get(Survey, survey_id).rr_counter == 1
        assert (
            session.query(SurveyScreen).filter(SurveyScreen.respondent_id == person.id).count() == 2
        )
