"""Request and response bodies of the REST API (pydantic models, shown in ``/docs``)."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import Query
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
)

from app.core.json_types import JsonFloat, JsonInt, UtcDatetime
from app.core.limits import MAX_BATCH, MAX_INSTRUCTIONS_CHARS, MAX_NAME_CHARS, MAX_SEED
from app.models import StudyStatus
from app.recruiting.seats import OutcomeName
from app.studies.service import StudySpec
from engine.candidates import MAX_CANDIDATES
from engine.disagreement import MAX_PAIRS
from engine.envs import DEFAULT_ENV_ID
from engine.practice import MAX_PRACTICE_PAIRS, MIN_PRACTICE_PAIRS, check_practice_pairs


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
    allow_ties: StrictBool = Field(
        False,
        description='A participant may answer "can\'t tell"; the bracket then advances by a '
        "seeded coin.",
    )
    practice_pairs: Annotated[JsonInt, AfterValidator(check_practice_pairs)] = Field(
        0,
        description=f"Practice pairs before the bracket: 0 (none) or {MIN_PRACTICE_PAIRS} to "
        f"{MAX_PRACTICE_PAIRS}. Their states are not among the candidates; answers are not "
        "stored.",
        json_schema_extra={"minimum": 0, "maximum": MAX_PRACTICE_PAIRS},
    )
    clips: StrictBool = Field(
        False,
        description="Show participants 2 s motion clips of the candidates, rendered in the "
        "background after the study is ready (stills until then). The clip shows motion, "
        "but F, the advice reward, rewards the posture alone.",
    )

    def spec(self) -> StudySpec:
        """The study this request asks for, as the services take it."""
        return StudySpec(**self.model_dump())


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
    allow_ties: bool
    practice_pairs: int
    clips: bool
    clips_ready: bool = Field(description="Every candidate's clip is rendered.")
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
    clip_url: str | None = Field(
        None, description="Its motion clip (animated WebP), once rendered (studies with clips)."
    )
    clip_policy: str | None = Field(
        None,
        description='What rolled it forward in its clip ("baseline run 3", "random '
        'actions"); null without a clip.',
    )
    clip_seed: int | None = Field(
        None, description="The reset seed of its clip (which also seeds random actions)."
    )


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
    excluded: bool = Field(False, description="Left out of pooling and exports (labels kept).")
    exclusion_reason: str | None = Field(
        None, description="Why excluded, or that the researcher included them again."
    )
    share_consent: bool = Field(
        False,
        description="Agreed that their labels may be shared in a public dataset, under a "
        "pseudonym (PUT /api/participants/me/share-consent).",
    )
    outcome: OutcomeName = Field(
        "in_progress",
        description="What became of them: withdrawn and timed-out participants are left out "
        "of trees, pooling, exports and the dataset (timed-out ones included on request).",
    )
    code: str | None = Field(
        None, description="The open link's code for their outcome (null: none, or invited)."
    )
    deadline_at: UtcDatetime | None = Field(
        None, description="When their time runs out (the open link's time limit)."
    )
    withdrawn_at: UtcDatetime | None = None


#: The exports' query parameter: also the labels of excluded participants.
IncludeExcluded = Annotated[
    bool,
    Query(
        description="Also the labels (or trees) of participants excluded from pooling and "
        "exports (in label exports their ``excluded`` column is true); by default they are "
        "left out."
    ),
]


class ExclusionIn(BaseModel):
    """The researcher's decision on a participant: exclude them from pooling and exports,
    or include them again (their labels are kept either way)."""

    model_config = ConfigDict(extra="forbid")

    excluded: StrictBool
    reason: str | None = Field(None, min_length=1, max_length=200)
