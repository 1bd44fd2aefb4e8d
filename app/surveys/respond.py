"""Survey respondents: invite links, their screens (order and left/right placement drawn by a
seeded generator and stored) and round-robin assignment. Their answers are
:mod:`app.surveys.answers`.

A respondent's screens are planned once, by the first request that claims them with an atomic
``UPDATE survey_respondents SET started_at = now WHERE started_at IS NULL``: a concurrent
request for the same respondent waits for that row lock (PostgreSQL) or the writer lock
(SQLite), finds the row claimed, and reads the plan the winner stored. Round-robin stimuli
come from ``UPDATE surveys SET rr_counter = rr_counter + 1 ... RETURNING rr_counter``, which
the database performs atomically, so concurrent respondents never get the same slot.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import func, select, update
from sqlalchemy.orm import Session

from app.core.auth import new_token
from app.core.limits import MAX_BATCH, check_text
from app.db import writing
from app.models import (
    Survey,
    SurveyRespondent,
    SurveyScreen,
    SurveyStimulus,
    utcnow,
)
from app.recruiting.members import SURVEY
from app.surveys.service import get_survey, questions_for, stimuli_of
from engine.errors import InputError

RESPONDENT_COOKIE = SURVEY.cookie


def invite_path(token: str) -> str:
    """The invite link's path (it sets the respondent cookie, as ``/p/<token>`` does)."""
    return SURVEY.invite_path(token)


def add_respondents(
    session: Session, *, survey_id: int, count: int = 1, name: str | None = None
) -> list[SurveyRespondent]:
    """Invite ``count`` respondents (each gets an unguessable invite token)."""
    if not 1 <= count <= MAX_BATCH:
        raise InputError(f"count must be in 1..{MAX_BATCH}, got {count}")
    check_text(name=name)
    get_survey(session, survey_id=survey_id)
    people = [
        SurveyRespondent(survey_id=survey_id, token=new_token(), name=name) for _ in range(count)
    ]
    with writing(session):
        session.add_all(people)
    return people


def respondent_rng(survey: Survey, respondent_id: int) -> np.random.Generator:
    """The generator of one respondent's order and placement: seeded by the survey's seed and
    the respondent's id, so a plan can be recomputed and checked."""
    return np.random.default_rng([survey.seed, respondent_id])


def plan_screens(
    rng: np.random.Generator, *, stimulus_ids: list[int], attention_id: int | None
) -> list[tuple[int, bool]]:
    """``(stimulus id, Tree 1 on the left?)`` per screen: the stimuli in a random order with
    the attention check (if any) at a random place, each placement a fair coin."""
    order = [stimulus_ids[i] for i in rng.permutation(len(stimulus_ids))]
    if attention_id is not None:
        order.insert(int(rng.integers(len(order) + 1)), attention_id)
    return [(sid, bool(rng.integers(2))) for sid in order]


def _round_robin_slot(session: Session, survey_id: int) -> int:
    """The next value of the survey's counter (0, 1, 2, ...), atomically."""
    counter = session.execute(
        update(Survey)
        .where(Survey.id == survey_id)
        .values(rr_counter=Survey.rr_counter + 1)
        .returning(Survey.rr_counter)
    ).scalar_one()
    return counter - 1


def start(session: Session, *, respondent: SurveyRespondent) -> list[SurveyScreen]:
    """The respondent's screens, planned on their first visit (idempotent, race-free)."""
    if respondent.started_at is None:  # else planned before: no write transaction needed
        survey = get_survey(session, survey_id=respondent.survey_id)
        with writing(session):
            claimed = session.execute(
                update(SurveyRespondent)
                .where(SurveyRespondent.id == respondent.id, SurveyRespondent.started_at.is_(None))
                .values(started_at=utcnow())
            ).rowcount  # type: ignore[attr-defined]
            if claimed:
                _store_plan(session, survey, respondent)
    return screens_of(session, respondent_id=respondent.id)


def _store_plan(session: Session, survey: Survey, respondent: SurveyRespondent) -> None:
    stimuli = stimuli_of(session, survey_id=survey.id)
    main = [s.id for s in stimuli if not s.attention_check]
    attention = next((s.id for s in stimuli if s.attention_check), None)
    if survey.assignment == "round_robin":
        main = [main[_round_robin_slot(session, survey.id) % len(main)]]
        session.execute(
            update(SurveyRespondent)
            .where(SurveyRespondent.id == respondent.id)
            .values(stimulus_id=main[0])
        )
    plan = plan_screens(
        respondent_rng(survey, respondent.shown_id), stimulus_ids=main, attention_id=attention
    )
    session.add_all(
        SurveyScreen(respondent_id=respondent.id, position=i, stimulus_id=sid, tree1_left=left)
        for i, (sid, left) in enumerate(plan, 1)
    )


def screens_of(session: Session, *, respondent_id: int) -> list[SurveyScreen]:
    return list(
        session.scalars(
            select(SurveyScreen)
            .where(SurveyScreen.respondent_id == respondent_id)
            .order_by(SurveyScreen.position)
        )
    )


#: What ``static/js/tree.js`` draws of a node; nothing else of a tree reaches a respondent.
DRAWN_NODE_FIELDS = ("state", "parent", "height", "depth", "weight", "reward")


def _tree_view(tree: dict[str, Any], *, survey: Survey) -> dict[str, Any]:
    """One tree as a respondent's page draws it, and no more: its nodes' shape, named by the
    tree (the judge's name would say whose tree it is, and an agent's tree alone carries
    per-candidate scores); highlights only if the survey shows them."""
    shape = tree["doc"]["tree"]
    nodes = [{k: n[k] for k in DRAWN_NODE_FIELDS} for n in shape["nodes"]]
    return {
        "name": tree["name"],
        "doc": {"judge": tree["name"], "tree": {"root": shape["root"], "nodes": nodes}},
        "study_id": tree["study_id"],
        "highlight": tree["highlight"] if survey.highlights else [],
    }


def screen_view(
    session: Session, *, survey: Survey, screen: SurveyScreen, total: int
) -> dict[str, Any]:
    """A screen as the respondent's page gets it: no expected answers, nothing that says
    which screen is the attention check."""
    stimulus = session.get_one(SurveyStimulus, screen.stimulus_id)
    one, two = (_tree_view(t, survey=survey) for t in stimulus.trees)
    left, right = (one, two) if screen.tree1_left else (two, one)
    questions = [
        {k: q[k] for k in ("key", "kind", "text", "options", "confidence")}
        for q in questions_for(survey, stimulus)
    ]
    return {
        "position": screen.position,
        "total": total,
        "left": left,
        "right": right,
        "questions": questions,
    }


def next_screen(
    session: Session, *, respondent: SurveyRespondent
) -> tuple[Survey, SurveyScreen, int] | None:
    """The first unanswered screen (marked shown), or ``None`` when every one is answered."""
    plan = start(session, respondent=respondent)
    todo = next((s for s in plan if s.answered_at is None), None)
    if todo is None:
        return None
    if todo.shown_at is None:
        with writing(session):
            session.execute(
                update(SurveyScreen)
                .where(
                    SurveyScreen.respondent_id == respondent.id,
                    SurveyScreen.position == todo.position,
                    SurveyScreen.shown_at.is_(None),
                )
                .values(shown_at=utcnow())
            )
    return get_survey(session, survey_id=respondent.survey_id), todo, len(plan)


def progress(session: Session, *, respondent_id: int) -> tuple[int, int]:
    """``(screens answered, screens planned)`` (``0, 0`` before the first visit)."""
    done, total = session.execute(
        select(func.count(SurveyScreen.answered_at), func.count(SurveyScreen.position)).where(
            SurveyScreen.respondent_id == respondent_id
        )
    ).one()
    return done, total


def list_respondents(session: Session, *, survey_id: int) -> list[SurveyRespondent]:
    get_survey(session, survey_id=survey_id)
    return list(
        session.scalars(
            select(SurveyRespondent)
            .where(SurveyRespondent.survey_id == survey_id)
            .order_by(SurveyRespondent.id)
        )
    )
