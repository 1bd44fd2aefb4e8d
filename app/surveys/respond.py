"""Survey respondents: invite links, their screens (order and left/right placement drawn by a
seeded generator and stored), round-robin assignment, and final answers.

A respondent's screens are planned once, by the first request that claims them with an atomic
``UPDATE survey_respondents SET started_at = now WHERE started_at IS NULL``: a concurrent
request for the same respondent waits for that row lock (PostgreSQL) or the writer lock
(SQLite), finds the row claimed, and reads the plan the winner stored. Round-robin stimuli
come from ``UPDATE surveys SET rr_counter = rr_counter + 1 ... RETURNING rr_counter``, which
the database performs atomically, so concurrent respondents never get the same slot.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.auth import new_token
from app.core.errors import ConflictError, NotFoundError
from app.core.limits import check_text
from app.db import writing
from app.models import (
    Survey,
    SurveyAnswer,
    SurveyRespondent,
    SurveyScreen,
    SurveyStimulus,
    utcnow,
)
from app.recruiting.members import SURVEY
from app.surveys.service import get_survey, questions_for, stimuli_of
from engine.errors import InputError

RESPONDENT_COOKIE = SURVEY.cookie
MAX_BATCH = 500
MAX_TEXT_ANSWER_CHARS = 2_000
#: Longest time on one screen that is stored (a day; longer is a tab left open).
MAX_SCREEN_MS = 24 * 3600 * 1000


@dataclass(frozen=True)
class AnswerIn:
    """One answer as a respondent sends it."""

    value: str
    confidence: int | None = None


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
        respondent_rng(survey, respondent.id), stimulus_ids=main, attention_id=attention
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


def _tree_view(tree: dict[str, Any], *, survey: Survey) -> dict[str, Any]:
    """One tree as a respondent's page draws it (highlights only if the survey shows them;
    the judge's name, which would say whose tree it is, replaced by the tree's)."""
    return {
        "name": tree["name"],
        "doc": tree["doc"] | {"judge": tree["name"]},
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


def _checked(questions: list[dict[str, Any]], answers: dict[str, AnswerIn]) -> None:
    """Every question of the screen answered, each with a valid value and confidence."""
    keys = [q["key"] for q in questions]
    if sorted(answers) != sorted(keys):
        raise InputError(
            f"answer exactly the questions {', '.join(keys)} "
            f"(got {', '.join(sorted(answers)) or 'none'})"
        )
    for q in questions:
        given = answers[q["key"]]
        if q["options"] and given.value not in q["options"]:
            raise InputError(f"{q['key']}: answer one of {', '.join(q['options'])}")
        if not q["options"] and not 0 < len(given.value.strip()) <= MAX_TEXT_ANSWER_CHARS:
            raise InputError(f"{q['key']}: write 1..{MAX_TEXT_ANSWER_CHARS} characters")
        if q["confidence"] != (given.confidence is not None):
            raise InputError(
                f"{q['key']}: "
                + ("rate your confidence from 1 to 5" if q["confidence"] else "takes no confidence")
            )
        if given.confidence is not None and not 1 <= given.confidence <= 5:
            raise InputError(f"{q['key']}: confidence must be 1..5")
        check_text(**{q["key"]: given.value})


def submit(
    session: Session,
    *,
    respondent: SurveyRespondent,
    position: int,
    answers: dict[str, AnswerIn],
    screen_ms: int,
) -> bool:
    """Store a screen's answers; ``True`` if stored now, ``False`` if the same were stored
    before. Answers are final.

    Raises:
        NotFoundError: no such screen for this respondent.
        ConflictError: the screen was answered differently before.
        InputError: answers that do not fit the screen's questions.
    """
    if not 0 <= screen_ms <= MAX_SCREEN_MS:
        raise InputError(f"screen_ms must be in 0..{MAX_SCREEN_MS}")
    plan = start(session, respondent=respondent)
    screen = next((s for s in plan if s.position == position), None)
    if screen is None:
        raise NotFoundError(f"screen {position} not found (this survey has {len(plan)})")
    survey = get_survey(session, survey_id=respondent.survey_id)
    _checked(questions_for(survey, session.get_one(SurveyStimulus, screen.stimulus_id)), answers)
    if screen.answered_at is not None:
        return _same_as_stored(session, screen, answers)
    try:
        _store(session, screen, answers, screen_ms)
    except IntegrityError:  # a concurrent submit of the same screen won
        return _same_as_stored(session, screen, answers)
    return True


def _store(
    session: Session,
    screen: SurveyScreen,
    answers: dict[str, AnswerIn],
    screen_ms: int,
) -> None:
    """Store one screen's answers and, if no screen is left unanswered, mark the respondent
    finished: decided inside the write transaction from what is stored, so two screens
    submitted at once cannot both see the other one unanswered."""
    now = utcnow()
    with writing(session):
        _lock_respondent(session, screen.respondent_id)
        session.add_all(
            SurveyAnswer(
                respondent_id=screen.respondent_id,
                stimulus_id=screen.stimulus_id,
                question=key,
                value=a.value,
                confidence=a.confidence,
                created_at=now,
            )
            for key, a in answers.items()
        )
        session.execute(
            update(SurveyScreen)
            .where(
                SurveyScreen.respondent_id == screen.respondent_id,
                SurveyScreen.position == screen.position,
            )
            .values(answered_at=now, screen_ms=screen_ms)
        )
        left = session.scalar(
            select(func.count(SurveyScreen.position)).where(
                SurveyScreen.respondent_id == screen.respondent_id,
                SurveyScreen.answered_at.is_(None),
            )
        )
        if left == 0:
            session.execute(
                update(SurveyRespondent)
                .where(
                    SurveyRespondent.id == screen.respondent_id,
                    SurveyRespondent.finished_at.is_(None),
                )
                .values(finished_at=now)
            )


def _lock_respondent(session: Session, respondent_id: int) -> None:
    """Hold the respondent's row until the transaction ends, so the submits of one respondent
    take turns: on PostgreSQL (READ COMMITTED) the second then counts the first's committed
    screen; on SQLite the engine's single writer lock already serialises them."""
    session.execute(
        select(SurveyRespondent.id).where(SurveyRespondent.id == respondent_id).with_for_update()
    )


def _same_as_stored(session: Session, screen: SurveyScreen, answers: dict[str, AnswerIn]) -> bool:
    stored = {
        a.question: (a.value, a.confidence)
        for a in session.scalars(
            select(SurveyAnswer).where(
                SurveyAnswer.respondent_id == screen.respondent_id,
                SurveyAnswer.stimulus_id == screen.stimulus_id,
            )
        )
    }
    if stored != {k: (a.value, a.confidence) for k, a in answers.items()}:
        raise ConflictError(
            f"screen {screen.position} was already answered differently; answers are final"
        )
    return False


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
