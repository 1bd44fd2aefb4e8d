"""A respondent's answers to a screen: checked against the screen's questions, stored once
(answers are final; the same answers again are accepted, different ones refused), and the
respondent marked finished with their last screen.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.core.limits import check_text
from app.db import writing
from app.models import Member, SurveyAnswer, SurveyRespondent, SurveyScreen, SurveyStimulus, utcnow
from app.recruiting import events
from app.surveys.crowd import LINK
from app.surveys.respond import start
from app.surveys.service import get_survey, questions_for
from engine.errors import InputError

MAX_TEXT_ANSWER_CHARS = 2_000
#: Longest time on one screen that is stored (a day; longer is a tab left open).
MAX_SCREEN_MS = 24 * 3600 * 1000


@dataclass(frozen=True)
class AnswerIn:
    """One answer as a respondent sends it."""

    value: str
    confidence: int | None = None


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
        _finish_if_done(session, screen.respondent_id, now)


def _finish_if_done(session: Session, respondent_id: int, now: datetime) -> None:
    """Mark the respondent finished once no screen of theirs is left unanswered
    (``respondent.finished`` and ``survey.target_reached``: :mod:`app.recruiting.events`)."""
    left = session.scalar(
        select(func.count(SurveyScreen.position)).where(
            SurveyScreen.respondent_id == respondent_id, SurveyScreen.answered_at.is_(None)
        )
    )
    if left == 0:
        done = session.execute(
            update(Member)
            .where(Member.id == respondent_id, Member.finished_at.is_(None))
            .values(finished_at=now)
            .returning(Member.collection_id)
        ).scalar_one_or_none()
        if done is not None:  # just finished: the webhook events, in this transaction
            shown = select(SurveyRespondent.shown_id).where(SurveyRespondent.id == respondent_id)
            events.finished(
                session,
                LINK,
                member_id=respondent_id,
                owner_id=done,
                shown_id=session.scalar(shown),
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
