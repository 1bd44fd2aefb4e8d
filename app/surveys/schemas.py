"""Bodies of the survey API (pydantic). Integers and booleans are strict: JSON ``true``,
``3.0``, ``1.5`` or ``"1"`` where an integer belongs (or ``1`` for a boolean) is a 422."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.core.json_types import JsonInt
from app.surveys import answers as surveys_answers
from app.surveys import respond
from app.surveys import service as surveys
from app.surveys.service import AttentionSpec, QuestionSpec, StimulusSpec, SurveySpec
from app.surveys.sources import TreeSource

_FORBID = ConfigDict(extra="forbid")
Id = Annotated[JsonInt, Field(ge=1, le=2**31 - 1)]
Text = Annotated[str, Field(max_length=surveys.MAX_QUESTION_CHARS)]


class ParticipantTree(BaseModel):
    """A finished participant's Human Preference Tree."""

    model_config = _FORBID
    kind: Literal["participant"]
    participant_id: Id


class RunTree(BaseModel):
    """A run's Agent Preference Tree at a checkpoint, as its stored artefact holds it."""

    model_config = _FORBID
    kind: Literal["run"]
    run_id: Id
    checkpoint: Annotated[JsonInt, Field(ge=0, le=2**62)]
    judge: str = Field(min_length=1, max_length=32)


class UploadedTree(BaseModel):
    """An ``acv.tree/1`` document; ``study_id`` names the study whose images to draw."""

    model_config = _FORBID
    kind: Literal["upload"]
    doc: dict[str, Any]
    study_id: Id | None = None


TreeIn = Annotated[ParticipantTree | RunTree | UploadedTree, Field(discriminator="kind")]


def _source(tree: ParticipantTree | RunTree | UploadedTree) -> TreeSource:
    return TreeSource(**tree.model_dump())


class StimulusIn(BaseModel):
    model_config = _FORBID
    label: str = Field("", max_length=200)
    tree1: TreeIn
    tree2: TreeIn
    expected: dict[str, str] = Field(
        default_factory=dict,
        max_length=surveys.MAX_QUESTIONS,
        description="Expected answers on this stimulus only.",
    )


class QuestionIn(BaseModel):
    model_config = _FORBID
    kind: Literal["choice", "yesno", "likert", "text"]
    text: Text = Field(min_length=1)
    options: list[Annotated[str, Field(max_length=surveys.MAX_OPTION_CHARS)]] = Field(
        default_factory=list, max_length=surveys.MAX_OPTIONS
    )
    points: Literal[5, 7] = 5
    expected: str | None = Field(None, max_length=surveys.MAX_OPTION_CHARS)
    confidence: StrictBool = False


class PaperTerms(BaseModel):
    """The bracketed text of the paper's Q2: "Tree 1 prefers ⟨tree1⟩. Does Tree 2 prefer
    ⟨tree2⟩?"."""

    model_config = _FORBID
    # default= by keyword: type checkers only see a keyword default as one (else required).
    tree1: Text = Field(default=surveys.DEFAULT_TERMS[0], min_length=1)
    tree2: Text = Field(default=surveys.DEFAULT_TERMS[1], min_length=1)


class AttentionIn(BaseModel):
    model_config = _FORBID
    question: str = Field("q1", max_length=32)
    expected: str = Field("same", max_length=surveys.MAX_OPTION_CHARS)


class SurveyCreate(BaseModel):
    """A new survey (it opens at once). ``template: paper`` asks the paper's two questions
    (``paper_terms`` fills in Q2); ``blank`` asks ``questions``."""

    model_config = _FORBID
    name: str = Field(min_length=1, max_length=200)
    intro: str = Field("", max_length=surveys.MAX_INTRO_CHARS)
    template: Literal["paper", "blank"] = "paper"
    paper_terms: PaperTerms = Field(default_factory=PaperTerms)
    questions: list[QuestionIn] = Field(default_factory=list, max_length=surveys.MAX_QUESTIONS)
    stimuli: list[StimulusIn] = Field(min_length=1, max_length=surveys.MAX_STIMULI)
    attention_check: AttentionIn | None = None
    highlights: StrictBool = False
    assignment: Literal["all", "round_robin"] = "all"
    seed: Annotated[JsonInt, Field(ge=0, le=2**63 - 1)] | None = None

    def question_specs(self) -> list[QuestionSpec]:
        if self.template == "paper":
            return surveys.paper_questions(
                tree1_prefers=self.paper_terms.tree1, tree2_prefers=self.paper_terms.tree2
            )
        return [QuestionSpec(**q.model_dump()) for q in self.questions]

    def spec(self) -> SurveySpec:
        """The survey this request asks for, as the services take it."""
        attention = self.attention_check
        return SurveySpec(
            name=self.name,
            intro=self.intro,
            template=self.template,
            questions=self.question_specs(),
            stimuli=[
                StimulusSpec(_source(s.tree1), _source(s.tree2), s.label, s.expected)
                for s in self.stimuli
            ],
            attention=AttentionSpec(**attention.model_dump()) if attention else None,
            highlights_on=self.highlights,
            assignment=self.assignment,
            seed=self.seed,
        )


class SurveyOut(BaseModel):
    id: int
    name: str
    intro: str
    template: str
    questions: list[dict[str, Any]]
    highlights: bool
    assignment: str
    exclusion_rule: str
    seed: int
    stimuli: list[dict[str, Any]] = Field(default_factory=list)


class RespondentsCreate(BaseModel):
    model_config = _FORBID
    count: Annotated[JsonInt, Field(ge=1, le=respond.MAX_BATCH)] = 1
    name: str | None = Field(None, max_length=200)


class RespondentOut(BaseModel):
    id: int
    token: str
    invite_url: str
    started: bool
    finished: bool
    stimulus_id: int | None
    external_id: str | None = None
    external_ids: dict[str, str] = {}


class AnswerBody(BaseModel):
    model_config = _FORBID
    value: str = Field(max_length=surveys_answers.MAX_TEXT_ANSWER_CHARS)
    confidence: Annotated[JsonInt, Field(ge=1, le=5)] | None = None


class ScreenAnswers(BaseModel):
    """A screen's answers (question key -> answer) and the time on the screen."""

    model_config = _FORBID
    answers: dict[Annotated[str, Field(max_length=32)], AnswerBody] = Field(
        max_length=surveys.MAX_QUESTIONS
    )
    screen_ms: Annotated[JsonInt, Field(ge=0, le=surveys_answers.MAX_SCREEN_MS)]
