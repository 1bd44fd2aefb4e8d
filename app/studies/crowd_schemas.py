"""Bodies of a study's crowd API (issue 14): its open link with label-quality options, label
quality and agreement."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.core.json_types import JsonInt
from app.recruiting.schemas import OpenLinkIn
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS


class CrowdIn(OpenLinkIn):
    """A study's open link and label-quality options."""

    consistency_check: StrictBool = False
    speed_threshold_ms: JsonInt = Field(DEFAULT_SPEED_THRESHOLD_MS, ge=0, le=600_000)


class CrowdOut(CrowdIn):
    model_config = ConfigDict(from_attributes=True)

    study_id: int
    slug: str
    url: str
    joined: int
    declines: int


class SideBiasOut(BaseModel):
    """Share of left choices and the two-sided binomial test against one half."""

    labels: int
    left: int
    left_share: float | None
    p_value: float | None


class ParticipantQualityOut(BaseModel):
    participant_id: int
    name: str | None
    external_id: str | None
    position_bias: SideBiasOut
    median_response_ms: float | None
    fast: bool
    consistency_agrees: bool | None
    reliability: float = Field(
        description="MACE competence from the known-answer checks answered (0.25 before any; "
        "never from agreement with others): docs/method.md §2.13."
    )
    reliability_checks: int = Field(description="How many known-answer checks it rests on.")
    flags: list[str]


class QualityOut(BaseModel):
    study_id: int
    speed_threshold_ms: int
    position_bias: SideBiasOut
    participants: list[ParticipantQualityOut]


class PairAgreementOut(BaseModel):
    a: int
    b: int
    shared: int
    agreement: float | None


class TeacherAgreementOut(BaseModel):
    participant_id: int
    teacher: str
    labels: int
    agreement: float | None


class AgreementOut(BaseModel):
    study_id: int
    participants: list[int]
    pairs: list[PairAgreementOut]
    mean_agreement: float | None
    krippendorff_alpha: float | None
    shared_pairs: int
    teachers: list[TeacherAgreementOut]
