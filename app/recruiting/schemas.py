"""Bodies of the crowd API (issue 14): open-link settings, label quality and agreement."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, StrictBool

from app.recruiting.links import (
    DEFAULT_EXTERNAL_PARAMS,
    MAX_PARTICIPANTS,
    REDIRECT_URL_PATTERN,
)
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS
from app.studies.schemas import JsonInt

ParamName = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]{0,63}$")]


class OpenLinkIn(BaseModel):
    """An open link's options (a study's ``/s/<slug>``, a survey's ``/q/<slug>``)."""

    model_config = ConfigDict(extra="forbid")

    enabled: StrictBool = Field(description="Whether the open link admits visitors.")
    max_participants: JsonInt = Field(ge=1, le=MAX_PARTICIPANTS)
    external_params: list[ParamName] = Field(
        list(DEFAULT_EXTERNAL_PARAMS),
        min_length=1,
        max_length=10,
        description="Query parameters stored on the person; the first one identifies "
        "a returning person.",
    )
    consent_text: str | None = Field(None, min_length=1, max_length=20_000)
    completion_code: str | None = Field(None, min_length=1, max_length=100)
    redirect_url: str | None = Field(
        None,
        min_length=1,
        max_length=500,
        pattern=REDIRECT_URL_PATTERN,
        description="An http(s) URL to send people to.",
    )


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


class SurveyCrowdOut(OpenLinkIn):
    """A survey's open link with its counts: respondents who joined through it, declined
    consents, and joined respondents who finished."""

    model_config = ConfigDict(from_attributes=True)

    survey_id: int
    slug: str
    url: str
    joined: int
    declines: int
    completed: int


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
