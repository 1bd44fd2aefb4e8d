"""Tree-reading surveys (the paper's user study): questions, stimuli and creation.

A survey opens when it is created: its questions, stimuli (trees frozen as JSON), assignment
and exclusion rule never change afterwards, so every respondent answers the same survey.
Respondents: :mod:`app.surveys.respond`; results: :mod:`app.surveys.results`.
"""

from __future__ import annotations

import secrets
from dataclasses import dataclass, field
from typing import Any, Literal

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.core.limits import MAX_NAME_CHARS, MAX_SEED, check_text
from app.db import writing
from app.models import Survey, SurveyStimulus
from app.surveys.sources import TreeSource, frozen, highlights, resolve
from engine.errors import InputError

QuestionKind = Literal["choice", "yesno", "likert", "text"]
MAX_STIMULI = 20
MAX_QUESTIONS = 10
MAX_INTRO_CHARS = 5_000
MAX_QUESTION_CHARS = 500
MAX_OPTION_CHARS = 100
MAX_OPTIONS = 6
LIKERT_POINTS = (5, 7)
YES_NO = ("yes", "no")
DEFAULT_TERMS = ("a straight posture", "a bent posture")
PAPER_Q1 = "Do these two trees express the same preferences, or different ones?"
EXCLUSION_TEXT = {
    "none": "no exclusions (the survey has no attention check)",
    "attention_check": "exclude respondents who fail the attention check",
}


@dataclass(frozen=True)
class QuestionSpec:
    """A question as the researcher writes it (the blank template)."""

    kind: QuestionKind
    text: str
    options: list[str] = field(default_factory=list)  # choice only
    points: int = 5  # likert only
    expected: str | None = None
    confidence: bool = False


@dataclass(frozen=True)
class StimulusSpec:
    """Two trees and, optionally, expected answers that differ on this stimulus."""

    tree1: TreeSource
    tree2: TreeSource
    label: str = ""
    expected: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class AttentionSpec:
    """An extra stimulus with two identical trees; ``question`` must be answered ``expected``."""

    question: str = "q1"
    expected: str = "same"


def paper_questions(*, tree1_prefers: str, tree2_prefers: str) -> list[QuestionSpec]:
    """The paper's two questions, each followed by a confidence rating (1-5)."""
    return [
        QuestionSpec(
            "choice", PAPER_Q1, ["same", "different"], expected="different", confidence=True
        ),
        QuestionSpec(
            "yesno",
            f"Tree 1 prefers {tree1_prefers}. Does Tree 2 prefer {tree2_prefers}?",
            expected="yes",
            confidence=True,
        ),
    ]


def _question_json(index: int, spec: QuestionSpec) -> dict[str, Any]:
    """Validate one question; its stored form with key ``q<index>`` and its answer options."""
    if not spec.text.strip() or len(spec.text) > MAX_QUESTION_CHARS:
        raise InputError(f"question {index}: text must be 1..{MAX_QUESTION_CHARS} characters")
    options = _options(index, spec)
    if spec.expected is not None and spec.expected not in options:
        raise InputError(
            f"question {index}: expected answer {spec.expected!r} is not one of "
            f"its options ({', '.join(options) or 'free text has none'})"
        )
    check_text(text=spec.text, **{f"option {o}": o for o in options})
    return {
        "key": f"q{index}",
        "kind": spec.kind,
        "text": spec.text,
        "options": options,
        "expected": spec.expected,
        "confidence": spec.confidence,
    }


def _options(index: int, spec: QuestionSpec) -> list[str]:
    if spec.kind == "yesno":
        return list(YES_NO)
    if spec.kind == "likert":
        if spec.points not in LIKERT_POINTS:
            raise InputError(f"question {index}: a Likert scale has 5 or 7 points")
        return [str(i) for i in range(1, spec.points + 1)]
    if spec.kind == "text":
        return []
    options = [o.strip() for o in spec.options]
    if (
        not 2 <= len(options) <= MAX_OPTIONS
        or len(set(options)) != len(options)
        or not all(0 < len(o) <= MAX_OPTION_CHARS for o in options)
    ):
        raise InputError(
            f"question {index}: a forced choice needs 2..{MAX_OPTIONS} distinct "
            f"options of 1..{MAX_OPTION_CHARS} characters"
        )
    return options


def check_questions(specs: list[QuestionSpec]) -> list[dict[str, Any]]:
    """The stored questions (keys ``q1``, ``q2``, ...). Raises :class:`InputError`."""
    if not 1 <= len(specs) <= MAX_QUESTIONS:
        raise InputError(f"a survey has 1..{MAX_QUESTIONS} questions")
    return [_question_json(i, spec) for i, spec in enumerate(specs, start=1)]


def _check_expected(questions: list[dict[str, Any]], expected: dict[str, str], where: str) -> None:
    by_key = {q["key"]: q for q in questions}
    for key, value in expected.items():
        if key not in by_key:
            raise InputError(f"{where}: no question {key!r} (questions: {', '.join(by_key)})")
        if value not in by_key[key]["options"]:
            raise InputError(f"{where}: {value!r} is not an answer to {key}")


def _check_survey(*, name: str, intro: str, stimuli: list[StimulusSpec], seed: int) -> None:
    if not name.strip() or len(name) > MAX_NAME_CHARS:
        raise InputError(f"name must be 1..{MAX_NAME_CHARS} characters")
    if len(intro) > MAX_INTRO_CHARS:
        raise InputError(f"intro must be at most {MAX_INTRO_CHARS} characters")
    if not 1 <= len(stimuli) <= MAX_STIMULI:
        raise InputError(f"a survey has 1..{MAX_STIMULI} stimuli")
    if not 0 <= seed <= MAX_SEED:
        raise InputError(f"seed must be in 0..{MAX_SEED}")
    check_text(name=name, intro=intro, **{f"label {i}": s.label for i, s in enumerate(stimuli)})


def _stimulus(
    session: Session, spec: StimulusSpec, *, position: int, questions: list[dict[str, Any]]
) -> SurveyStimulus:
    """Resolve and freeze a stimulus's two trees (with what highlights would mark)."""
    where = f"stimulus {position}"
    _check_expected(questions, spec.expected, where)
    one, two = (resolve(session, source=spec.tree1), resolve(session, source=spec.tree2))
    marks1, marks2 = highlights(one.doc, two.doc)
    return SurveyStimulus(
        position=position,
        label=spec.label or f"Stimulus {position}",
        attention_check=False,
        trees=[
            frozen(one, name="Tree 1", highlight=marks1),
            frozen(two, name="Tree 2", highlight=marks2),
        ],
        expected=dict(spec.expected),
    )


def _attention(
    first: SurveyStimulus, spec: AttentionSpec, *, position: int, questions: list[dict[str, Any]]
) -> SurveyStimulus:
    """Two copies of the first stimulus's Tree 1: anyone reading them sees they are one."""
    question = next((q for q in questions if q["key"] == spec.question), None)
    if question is None or question["kind"] not in ("choice", "yesno"):
        raise InputError(
            f"attention check: {spec.question!r} is not a forced-choice or yes/no "
            "question of this survey"
        )
    _check_expected(questions, {spec.question: spec.expected}, "attention check")
    tree = first.trees[0]
    return SurveyStimulus(
        position=position,
        label="Attention check (identical trees)",
        attention_check=True,
        check_question=spec.question,
        trees=[tree | {"highlight": []}, tree | {"name": "Tree 2", "highlight": []}],
        expected={spec.question: spec.expected},
    )


@dataclass(frozen=True)
class SurveySpec:
    """A survey to create (``POST /api/surveys``'s body, as the services take it)."""

    name: str
    intro: str
    template: Literal["paper", "blank"]
    questions: list[QuestionSpec]
    stimuli: list[StimulusSpec]
    attention: AttentionSpec | None = None
    highlights_on: bool = False
    assignment: Literal["all", "round_robin"] = "all"
    #: None: drawn now.
    seed: int | None = None


def create_survey(session: Session, *, spec: SurveySpec) -> Survey:
    """Create (and open) a survey; every tree is resolved and frozen now.

    Raises:
        InputError: invalid fields, questions, expected answers or trees.
        NotFoundError, ConflictError: a named participant, run or checkpoint (see
            :func:`app.surveys.sources.resolve`).
    """
    seed = secrets.randbits(62) if spec.seed is None else spec.seed
    _check_survey(name=spec.name, intro=spec.intro, stimuli=spec.stimuli, seed=seed)
    stored = check_questions(spec.questions)
    rows = [
        _stimulus(session, stimulus, position=i, questions=stored)
        for i, stimulus in enumerate(spec.stimuli, start=1)
    ]
    if spec.attention is not None:
        rows.append(_attention(rows[0], spec.attention, position=len(rows) + 1, questions=stored))
    survey = Survey(
        name=spec.name,
        intro=spec.intro,
        template=spec.template,
        questions=stored,
        highlights=spec.highlights_on,
        assignment=spec.assignment,
        seed=seed,
        rr_counter=0,
        exclusion_rule="attention_check" if spec.attention else "none",
    )
    _store(session, survey, rows)
    return survey


def _store(session: Session, survey: Survey, stimuli: list[SurveyStimulus]) -> None:
    """Store a new survey and its stimuli in one transaction."""
    with writing(session):
        session.add(survey)
        session.flush()
        for row in stimuli:
            row.survey_id = survey.id
        session.add_all(stimuli)


def get_survey(session: Session, *, survey_id: int) -> Survey:
    """The survey, or :class:`NotFoundError`."""
    survey = session.get(Survey, survey_id)
    if survey is None:
        raise NotFoundError(f"survey {survey_id} not found")
    return survey


def list_surveys(session: Session) -> list[Survey]:
    """Every survey, newest first."""
    return list(session.scalars(select(Survey).order_by(Survey.id.desc())))


def stimuli_of(session: Session, *, survey_id: int) -> list[SurveyStimulus]:
    """The survey's stimuli in order (the attention check last)."""
    return list(
        session.scalars(
            select(SurveyStimulus)
            .where(SurveyStimulus.survey_id == survey_id)
            .order_by(SurveyStimulus.position)
        )
    )


def questions_for(survey: Survey, stimulus: SurveyStimulus) -> list[dict[str, Any]]:
    """The questions asked on ``stimulus`` with its expected answers (an attention check asks
    only its check question)."""
    asked = [
        q
        for q in survey.questions
        if not stimulus.attention_check or q["key"] == stimulus.check_question
    ]
    return [q | {"expected": stimulus.expected.get(q["key"], q["expected"])} for q in asked]


def exclusion_text(survey: Survey) -> str:
    """The exclusion rule in words, as the results page shows it."""
    return EXCLUSION_TEXT[survey.exclusion_rule]
