"""Request and response bodies of the REST API (pydantic models, shown in ``/docs``)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationInfo,
)

from app.labelling.service import MAX_RESPONSE_MS
from app.models import StudyStatus, as_utc
from app.studies.participants import MAX_BATCH
from app.studies.service import MAX_INSTRUCTIONS_CHARS, MAX_NAME_CHARS, MAX_SEED
from engine.candidates import MAX_CANDIDATES
from engine.disagreement import MAX_PAIRS
from engine.envs import DEFAULT_ENV_ID

#: Validation context of HTML forms, whose every field is text: there ``"3"`` is an integer.
FORM_INPUT = {"form": True}


def _json_number(kind: str) -> Any:
    def check(value: Any, info: ValidationInfo) -> Any:
        from_form = isinstance(value, str) and bool(info.context and info.context.get("form"))
        if (
            isinstance(value, bool)
            or (isinstance(value, str) and not from_form)
            or (kind == "integer" and isinstance(value, float))
        ):
            # lax pydantic reads true as 1, "3" as 3 and 3.0 as 3
            raise ValueError(f"must be a JSON {kind}")
        return value

    return check


#: The one rule for an integer of a request body: a JSON integer literal (``3``), never
#: ``3.0``, ``true`` (a JSON ``false`` is not 0) or ``"3"``; an HTML form's text ``"3"`` is
#: read with :data:`FORM_INPUT`. Every integer field of a request body is one
#: (``tests/app/test_strict_integers.py`` checks them all, from the OpenAPI document).
JsonInt = Annotated[int, BeforeValidator(_json_number("integer"))]
#: A JSON number (an integer too), never ``true`` or ``"0.5"``.
JsonFloat = Annotated[float, BeforeValidator(_json_number("number"))]
#: Stored times are UTC; SQLite hands them back naive.
UtcDatetime = Annotated[datetime, AfterValidator(as_utc)]


class StudyCreate(BaseModel):
    """A new study. Candidates are sampled and rendered after the 201 answer."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(min_length=1, max_length=MAX_NAME_CHARS)
    env_id: str = Field(
        DEFAULT_ENV_ID,
        min_length=1,
        max_length=100,
        description="A Gymnasium MuJoCo env id, e.g. Humanoid-v5.",
    )
    n_candidates: JsonInt = Field(ge=2, le=MAX_CANDIDATES)
    p: JsonFloat = Field(
        0.9,
        ge=0.0,
        le=1.0,
        allow_inf_nan=False,
        description="Braverman-Mossel coin probability of the seeding.",
    )
    seed: JsonInt = Field(0, ge=0, le=MAX_SEED)
    disagreement_pairs: JsonInt = Field(
        0,
        ge=0,
        le=MAX_PAIRS,
        description="Extra pairs asked after the bracket, where the participant's advice and "
        "a no-advice baseline disagree (never part of the tree); > 0 needs a finished "
        "no-advice ppo run on the env (any study's).",
    )
    sampling: Literal["uniform", "diverse", "informative"] = Field(
        "uniform",
        description="informative needs a finished no-advice ppo run on the env (any study's).",
    )
    instructions: str = Field(
        "",
        max_length=MAX_INSTRUCTIONS_CHARS,
        description="Shown to participants before the first match.",
    )


class StudyOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    env_id: str
    n_candidates: int
    p: float
    seed: int
    sampling: str
    disagreement_pairs: int
    instructions: str
    status: StudyStatus
    error: str | None
    created_at: UtcDatetime


class CandidateOut(BaseModel):
    id: int
    env_reward: float
    baseline_return: float | None = Field(
        description="The study's no-advice baseline's return from this state (studies that "
        "ask disagreement pairs; null otherwise)."
    )
    qpos: list[float]
    qvel: list[float]
    image_url: str
    thumb_url: str


class AdvicePowerOut(BaseModel):
    """Can a participant's advice be told apart on this bracket and their disagreement pairs
    (estimated from the study's baseline where it has one, else from R)?"""

    participant_id: int
    n_matches: int
    contested: int = Field(
        description="Informative matches where the baseline (else R) picks the other winner."
    )
    uninformative: int = Field(description="Matches where the advice or R has no preference.")
    min_detectable_delta: float | None = Field(
        description="Smallest Δ an experiment detects (α 0.05, power 0.8); null: none."
    )
    can_tell: bool = Field(description="At least 8 contested matches.")


class ProgressOut(BaseModel):
    done: int
    total: int


class ParticipantCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")

    name: str | None = Field(
        None, max_length=MAX_NAME_CHARS, description="Optional note, e.g. who was invited."
    )


class ParticipantBatchCreate(ParticipantCreate):
    count: JsonInt = Field(ge=1, le=MAX_BATCH)


class ParticipantCreated(BaseModel):
    id: int
    study_id: int
    token: str
    invite_url: str


class ParticipantOut(ParticipantCreated):
    name: str | None
    progress: ProgressOut
    finished: bool
    created_at: UtcDatetime
    finished_at: UtcDatetime | None


class MeOut(BaseModel):
    """What a participant may know about themselves and their study."""

    id: int
    study_id: int
    study_name: str
    instructions: str
    progress: ProgressOut
    finished: bool
    can_undo: bool


class MatchSide(BaseModel):
    candidate_id: int
    image_url: str
    thumb_url: str


class NextMatchOut(BaseModel):
    """Round ``round`` of ``n_rounds``, match ``match_number`` of ``matches_in_round``."""

    match_id: int
    round: int
    n_rounds: int
    match_number: int
    matches_in_round: int
    a: MatchSide
    b: MatchSide
    left: int = Field(
        description="The candidate id shown on the left (``a``'s or ``b``'s; "
        "sides are randomised per participant and match)."
    )
    progress: ProgressOut


class LabelIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    winner: JsonInt = Field(ge=0, le=2**31 - 1, description="The preferred candidate's id.")
    response_ms: Annotated[JsonInt, Field(ge=0, le=MAX_RESPONSE_MS)] | None = Field(
        None, description="Time the participant took; estimated by the server when absent."
    )


class LabelOut(BaseModel):
    match_id: int
    winner: int
    created: bool
    progress: ProgressOut
    finished: bool
    next: NextMatchOut | None = Field(
        description="The match to decide now (as next-match answers); null once finished."
    )


class PairOut(BaseModel):
    """A disagreement pair after the bracket: never part of the tree."""

    position: int = Field(description="Its place among the participant's pairs, from 0.")
    total: int = Field(description="How many pairs the participant is asked.")
    left: int
    right: int
    left_image_url: str
    right_image_url: str
    winner: int | None = Field(description="The answer; null while open.")


class UndoOut(BaseModel):
    """The match that is open again."""

    match_id: int
    round: int
    progress: ProgressOut


class BracketCellOut(BaseModel):
    round: int
    slot: int
    a: int | None
    b: int | None
    winner: int | None
    match_id: int | None
    is_bye: bool


class BracketOut(BaseModel):
    rounds: list[list[BracketCellOut]]
