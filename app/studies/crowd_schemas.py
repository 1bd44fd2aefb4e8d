"""Bodies of a study's crowd API (issue 14): its open link with label-quality options, label
quality and agreement."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.core.json_types import JsonFloat, JsonInt
from app.recruiting.schemas import OpenLinkIn
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS


class CrowdIn(OpenLinkIn):
    """A study's open link and label-quality options."""

    consistency_check: StrictBool = False
    speed_threshold_ms: JsonInt = Field(DEFAULT_SPEED_THRESHOLD_MS, ge=0, le=600_000)
    gold_gate: JsonFloat | None = Field(
        None,
        ge=0.0,
        le=1.0,
        allow_inf_nan=False,
        description="Qualification gate: flag a participant whose gold accuracy's 95% "
        "Clopper-Pearson upper bound is below it (null: no gate).",
    )
    gate_excludes: StrictBool = Field(
        False,
        description="Also exclude the participants the gate flags from pooling and exports "
        "(their labels are kept; off: flags only). A participant it flags after 2 or more "
        "failed gold items is stopped, and given gate_code.",
    )
    gate_code: str | None = Field(
        None,
        min_length=1,
        max_length=100,
        description="The code of a participant the gate stops (e.g. one the researcher "
        "reviews by hand).",
    )


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
    gold_right: int = Field(description="Gold items answered right.")
    gold_asked: int = Field(description="Gold items answered.")
    gold_interval: tuple[float, float] | None = Field(
        description="95% Clopper-Pearson interval of gold accuracy; null before any gold item."
    )
    ties: int = Field(description='Matches answered "can\'t tell".')
    excluded: bool = Field(description="Left out of pooling and exports (labels kept).")
    exclusion_reason: str | None
    flags: list[str]


class QualityOut(BaseModel):
    study_id: int
    speed_threshold_ms: int
    gold_gate: float | None
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
