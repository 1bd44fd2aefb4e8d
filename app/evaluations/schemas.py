"""Bodies of the evaluation API (pydantic): strict integers, numbers and booleans."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict

from app.core.json_types import JsonFloat, JsonInt, UtcDatetime
from app.core.limits import MAX_BATCH, MAX_NAME_CHARS
from app.evaluations import service
from app.models import StudyStatus
from engine.practice import MAX_PRACTICE_PAIRS

_FORBID = ConfigDict(extra="forbid")
RunId = Annotated[JsonInt, Field(ge=1, le=2**31 - 1)]
RunIds = Annotated[
    list[RunId],
    Field(min_length=service.MIN_RUNS_PER_ARM, max_length=service.MAX_RUNS_PER_ARM),
]


class EvaluationDesign(BaseModel):
    """Who answers, what they see, and what the design is sized for."""

    model_config = _FORBID
    evaluator_kind: Literal["advisor", "others"] = Field(
        "others",
        description="'advisor': the person whose tree trained the advised runs, asked which "
        "agent is closer to what they asked for; 'others': people shown the study's "
        "instructions, asked which agent follows them better.",
    )
    stimulus: Literal["still", "clip"] = Field(
        "clip",
        description="Clips of each agent moving, or stills (clips fall back to stills "
        "until they are rendered).",
    )
    show_bracket: Annotated[bool, Strict()] = Field(
        False,
        description="Advisor only: show each pair with a folded reminder of the advisor's own "
        "bracket (the pictures they ranked highest); recorded with every answer "
        "(`reminder`). Off by default.",
    )
    pairs_per_evaluator: JsonInt = Field(service.DEFAULT_PAIRS, ge=1, le=service.MAX_PAIRS)
    target_win_rate: JsonFloat = Field(service.DEFAULT_TARGET, gt=0.5, lt=1)
    name: str | None = Field(None, min_length=1, max_length=MAX_NAME_CHARS)
    gold_pairs: JsonInt = Field(
        0,
        ge=0,
        le=service.MAX_GOLD_PAIRS,
        description='Instructed gold pairs per evaluator ("choose the picture with the '
        'marker"), placed at seeded positions among the real pairs and never counted in the '
        "result.",
    )
    gold_gate: JsonFloat | None = Field(
        None,
        gt=0,
        le=1,
        description="Leave out an evaluator whose gold accuracy is clearly below this "
        "fraction (the upper bound of its 95% Clopper-Pearson interval is below it); "
        "only with gold_pairs. Null: no gate.",
    )
    practice_pairs: JsonInt = Field(
        0,
        ge=0,
        le=MAX_PRACTICE_PAIRS,
        description="Practice pairs before the first real pair: 0 (none) or 2 to 5, on "
        "practice states of the env (never the evaluation's agents); nothing is stored.",
    )

    def spec(
        self,
        advised: list[int] | tuple[int, ...],
        baseline: list[int] | tuple[int, ...],
        experiment_id: int | None = None,
    ) -> service.EvaluationSpec:
        """The service's spec over these runs."""
        return service.EvaluationSpec(
            advised=tuple(advised),
            baseline=tuple(baseline),
            evaluator_kind=self.evaluator_kind,
            show_bracket=self.show_bracket,
            stimulus=self.stimulus,
            pairs_per_evaluator=self.pairs_per_evaluator,
            target_win_rate=self.target_win_rate,
            name=self.name,
            experiment_id=experiment_id,
            gold_pairs=self.gold_pairs,
            gold_gate=self.gold_gate,
            practice_pairs=self.practice_pairs,
        )


class EvaluationCreate(EvaluationDesign):
    """Any two groups of runs of one env, with the design."""

    advised_run_ids: RunIds
    baseline_run_ids: RunIds


class EvaluationOut(BaseModel):
    """An evaluation as the researcher sees it (never shown to evaluators)."""

    model_config = ConfigDict(from_attributes=True)
    id: int
    name: str
    env_id: str
    experiment_id: int | None
    evaluator_kind: str
    question: str
    advisor_id: int | None
    show_bracket: bool
    stimulus: str
    pairs_per_evaluator: int
    gold_pairs: int
    gold_gate: float | None
    practice_pairs: int
    target_win_rate: float
    needed_evaluators: int | None = Field(
        description="The fewest evaluators (of pairs_per_evaluator pairs each) that detect "
        "target_win_rate at 80% power with these runs (simulated; null while preparing, or "
        "when no number of evaluators does: runs, not answers, limit the design)."
    )
    design_power: float | None = Field(
        description="The simulated power at needed_evaluators (at 100 evaluators when none)."
    )
    status: StudyStatus
    clips_ready: bool
    error: str | None
    created_at: UtcDatetime


class EvaluatorsCreate(BaseModel):
    """How many evaluators to invite."""

    model_config = _FORBID
    count: JsonInt = Field(1, ge=1, le=MAX_BATCH)
    name: str | None = Field(None, min_length=1, max_length=MAX_NAME_CHARS)


class EvaluatorOut(BaseModel):
    """An evaluator, their invite link and progress."""

    id: int
    name: str | None
    invite_url: str
    done: int
    total: int
    finished: bool
    withdrawn: bool
    excluded: bool


class PairOut(BaseModel):
    """The evaluator's next pair: only its opaque key and where its pictures are."""

    key: str
    position: int
    total: int
    question: str
    left: dict[str, Any]
    right: dict[str, Any]
    reminder: list[dict[str, str]] | None = Field(
        None,
        description="The advisor's own bracket as a reminder (its pictures' `url` and `alt`, "
        "best first) when the evaluation shows it; null otherwise. Answers record it.",
    )


class AnswerIn(BaseModel):
    """An evaluator's answer to one pair."""

    model_config = _FORBID
    choice: Literal["left", "right", "tie"]
    response_ms: JsonInt | None = Field(None, ge=0, le=86_400_000)
    stimulus: Literal["still", "clip"] | None = Field(
        None,
        description="What the page showed (a reduced-motion page shows stills); "
        "by default what the pair's pictures are now.",
    )
