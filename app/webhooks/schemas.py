"""Request and response bodies of ``/api/webhooks``."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.core.json_types import JsonInt, UtcDatetime
from app.webhooks.outbox import Owner
from app.webhooks.targets import MAX_URL_CHARS

_DbId = Field(default=None, ge=1, le=2**31 - 1)


class WebhookIn(BaseModel):
    """A URL to POST a study's or a survey's events to: give exactly one of ``study_id`` and
    ``survey_id``."""

    model_config = ConfigDict(extra="forbid")

    study_id: JsonInt | None = _DbId
    survey_id: JsonInt | None = _DbId
    url: str = Field(
        min_length=1,
        max_length=MAX_URL_CHARS,
        description="An https URL of a public address (checked now, and before each delivery).",
    )

    @model_validator(mode="after")
    def _one_owner(self) -> WebhookIn:
        if (self.study_id is None) == (self.survey_id is None):
            raise ValueError("give exactly one of study_id and survey_id")
        return self

    def owner(self) -> Owner:
        if self.study_id is not None:
            return Owner("study", self.study_id)
        return Owner("survey", int(self.survey_id or 0))


class WebhookOut(BaseModel):
    """A webhook, its signing secret (Standard Webhooks, ``whsec_``) and its events by
    state: ``delivered``, ``pending`` (being retried) and ``failed`` (given up)."""

    id: int
    study_id: int | None
    survey_id: int | None
    url: str
    secret: str
    created_at: UtcDatetime
    delivered: int
    pending: int
    failed: int


class EventOut(BaseModel):
    """One event for one webhook: ``event_id`` is its ``webhook-id`` header, ``payload`` the
    body POSTed."""

    event_id: str
    type: str
    payload: dict[str, Any]
    created_at: UtcDatetime
    attempts: int
    next_attempt_at: UtcDatetime
    delivered_at: UtcDatetime | None
    status: Literal["delivered", "pending", "failed"]


class AttemptOut(BaseModel):
    """One delivery attempt: the receiver's HTTP status, or the error (no answer, a refused
    address, a redirect), and how long it took."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    event_id: str
    type: str
    attempted_at: UtcDatetime
    status_code: int | None
    error: str | None
    duration_ms: int
