"""A survey's results: per stimulus and question, n, counts, the proportion answering as
expected with its Clopper-Pearson 95% CI and an exact binomial test against chance, the mean
confidence and the median time on screen, without and with the survey's exclusions; and
exports with one row per answer (CSV, JSONL).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core import csv_export
from app.models import (
    Survey,
    SurveyAnswer,
    SurveyRespondent,
    SurveyScreen,
    SurveyStimulus,
    as_utc,
)
from app.surveys import stats
from app.surveys.service import exclusion_text, get_survey, questions_for, stimuli_of

EXPORT_COLUMNS = (
    "survey_id",
    "respondent_id",
    "external_id",
    "external_ids",
    "stimulus_id",
    "stimulus",
    "attention_check",
    "question",
    "value",
    "expected",
    "correct",
    "confidence",
    "screen_ms",
    "tree1_side",
    "excluded",
    "answered_at",
)


@dataclass(frozen=True)
class Row:
    """One stored answer with what the statistics need."""

    respondent_id: int
    stimulus: SurveyStimulus
    question: str
    value: str
    confidence: int | None
    screen_ms: int | None
    tree1_left: bool
    answered_at: Any


def answer_rows(session: Session, *, survey_id: int) -> list[Row]:
    """Every answer of the survey, in the order given."""
    stimuli = {s.id: s for s in stimuli_of(session, survey_id=survey_id)}
    rows = session.execute(
        select(
            SurveyAnswer, SurveyRespondent.shown_id, SurveyScreen.screen_ms, SurveyScreen.tree1_left
        )
        .join(SurveyRespondent, SurveyRespondent.id == SurveyAnswer.respondent_id)
        .join(
            SurveyScreen,
            (SurveyScreen.respondent_id == SurveyAnswer.respondent_id)
            & (SurveyScreen.stimulus_id == SurveyAnswer.stimulus_id),
        )
        .where(SurveyRespondent.survey_id == survey_id)
        .order_by(SurveyAnswer.id)
    )
    return [
        Row(
            shown_id,
            stimuli[a.stimulus_id],
            a.question,
            a.value,
            a.confidence,
            ms,
            left,
            a.created_at,
        )
        for a, shown_id, ms, left in rows
    ]


def failed_check(rows: Iterable[Row]) -> set[int]:
    """Respondents who answered an attention check other than expected."""
    return {
        r.respondent_id
        for r in rows
        if r.stimulus.attention_check
        and r.question == r.stimulus.check_question
        and r.value != r.stimulus.expected[r.question]
    }


def excluded(survey: Survey, rows: list[Row]) -> set[int]:
    """Who the survey's exclusion rule (fixed when it opened) leaves out."""
    return failed_check(rows) if survey.exclusion_rule == "attention_check" else set()


def _block(question: dict[str, Any], stimulus: SurveyStimulus, rows: list[Row]) -> dict[str, Any]:
    """The statistics of one question on one stimulus."""
    values = [r.value for r in rows]
    expected = question["expected"]
    out: dict[str, Any] = {
        "stimulus_id": stimulus.id,
        "stimulus": stimulus.label,
        "question": question["key"],
        "text": question["text"],
        "kind": question["kind"],
        "n": len(rows),
        "counts": {o: values.count(o) for o in question["options"]},
        "expected": expected,
        "accuracy": None,
        "mean_value": None,
        "versus_neutral": None,
        "mean_confidence": stats.mean([r.confidence for r in rows if r.confidence]),
        "median_time_ms": stats.median([r.screen_ms for r in rows if r.screen_ms is not None]),
    }
    if expected is not None and question["options"] and question["kind"] != "likert":
        result = stats.proportion(
            values.count(expected), len(values), chance=1 / len(question["options"])
        )
        out["accuracy"] = result.to_json() if result else None
    if question["kind"] == "likert":
        points = [int(v) for v in values]
        out["mean_value"] = stats.mean(points)
        leaning = stats.versus_neutral(points, neutral=(len(question["options"]) + 1) / 2)
        out["versus_neutral"] = leaning.to_json() if leaning else None
    if question["kind"] == "text":
        out["texts"] = values
    return out


def _blocks(
    survey: Survey, stimuli: list[SurveyStimulus], rows: list[Row], leave_out: set[int]
) -> list[dict[str, Any]]:
    kept = [r for r in rows if r.respondent_id not in leave_out]
    return [
        _block(q, s, [r for r in kept if r.stimulus.id == s.id and r.question == q["key"]])
        for s in stimuli
        if not s.attention_check
        for q in questions_for(survey, s)
    ]


def results(session: Session, *, survey_id: int) -> dict[str, Any]:
    """The results JSON (page, ``GET /api/surveys/{id}/results``, ``acv survey results``)."""
    survey = get_survey(session, survey_id=survey_id)
    stimuli = stimuli_of(session, survey_id=survey_id)
    rows = answer_rows(session, survey_id=survey_id)
    people = list(
        session.scalars(select(SurveyRespondent).where(SurveyRespondent.survey_id == survey_id))
    )
    leave_out = excluded(survey, rows)
    checked = {r.respondent_id for r in rows if r.stimulus.attention_check}
    return {
        "survey_id": survey.id,
        "name": survey.name,
        "assignment": survey.assignment,
        "exclusion_rule": exclusion_text(survey),
        "respondents": {
            "invited": len(people),
            "started": sum(p.started_at is not None for p in people),
            "finished": sum(p.finished_at is not None for p in people),
            "answered_attention_check": len(checked),
            "failed_attention_check": len(failed_check(rows)),
            "excluded": len(leave_out),
        },
        "paper": stats.paper_figures(),
        "without_exclusions": _blocks(survey, stimuli, rows, set()),
        "with_exclusions": _blocks(survey, stimuli, rows, leave_out),
    }


def _external_ids(session: Session, survey_id: int) -> dict[int, tuple[str | None, dict]]:
    """Each respondent's crowd platform ids (open link), by respondent id."""
    found = session.execute(
        select(
            SurveyRespondent.shown_id, SurveyRespondent.external_id, SurveyRespondent.external_ids
        ).where(SurveyRespondent.survey_id == survey_id)
    )
    return {rid: (key, ids or {}) for rid, key, ids in found}


def export_records(session: Session, *, survey_id: int) -> list[dict[str, Any]]:
    """One record per answer (columns :data:`EXPORT_COLUMNS`)."""
    survey = get_survey(session, survey_id=survey_id)
    rows = answer_rows(session, survey_id=survey_id)
    leave_out = excluded(survey, rows)
    external = _external_ids(session, survey_id)
    out = []
    for r in rows:
        asked = {q["key"]: q for q in questions_for(survey, r.stimulus)}
        expected = asked[r.question]["expected"] if r.question in asked else None
        out.append(
            {
                "survey_id": survey.id,
                "respondent_id": r.respondent_id,
                "external_id": external[r.respondent_id][0],
                "external_ids": external[r.respondent_id][1],
                "stimulus_id": r.stimulus.id,
                "stimulus": r.stimulus.label,
                "attention_check": r.stimulus.attention_check,
                "question": r.question,
                "value": r.value,
                "expected": expected,
                "correct": None if expected is None else r.value == expected,
                "confidence": r.confidence,
                "screen_ms": r.screen_ms,
                "tree1_side": "left" if r.tree1_left else "right",
                "excluded": r.respondent_id in leave_out,
                "answered_at": as_utc(r.answered_at).isoformat(),
            }
        )
    return out


def export_csv(session: Session, *, survey_id: int) -> str:
    """The records as CSV (:func:`app.core.csv_export.csv_text`: a text answer that
    would run as a formula gets a leading ``'``; ``external_ids`` is a JSON object)."""
    return csv_export.csv_text(
        EXPORT_COLUMNS,
        (
            {**record, "external_ids": json.dumps(record["external_ids"], sort_keys=True)}
            for record in export_records(session, survey_id=survey_id)
        ),
    )


def export_jsonl(session: Session, *, survey_id: int) -> str:
    return "".join(json.dumps(r) + "\n" for r in export_records(session, survey_id=survey_id))
