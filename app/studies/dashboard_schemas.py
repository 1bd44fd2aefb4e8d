"""Bodies of a study's live dashboard (issue 29 §1): ``GET /api/studies/{id}/dashboard``."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, Field


class LiveCountsOut(BaseModel):
    """Where the study's participants are now."""

    joined: int = Field(description="Participants: invited, or joined by the open link.")
    not_started: int = Field(description="Joined, no label yet.")
    labelling: int = Field(description="At least one label, bracket not finished.")
    finished: int = Field(description="Bracket finished.")
    declined: int = Field(description="Declined consent on the open link (0 without one).")
    excluded: int = Field(description="Left out of pooling and exports (labels kept).")
    withdrawn: int = Field(0, description="Withdrew after joining (labels kept, never used).")
    timed_out: int = Field(
        0, description="Past the open link's time limit, unfinished (their seats freed)."
    )


class LiveParticipantOut(BaseModel):
    """One participant's progress and cheap quality signals."""

    participant_id: int
    name: str | None
    external_id: str | None
    status: Literal["not_started", "labelling", "finished", "withdrawn", "failed_gate", "timed_out"]
    done: int = Field(description="Bracket matches decided.")
    total: int = Field(description="Matches in the bracket (N - 1).")
    median_response_ms: float | None = Field(
        description="Median time per decision; null before any label."
    )
    gold_right: int = Field(description="Gold items answered right.")
    gold_asked: int = Field(description="Gold items answered.")
    excluded: bool
    flags: list[str] = Field(
        description="As in /quality: position_bias, fast, inconsistent, below_gate."
    )


class DashboardOut(BaseModel):
    """A study's live dashboard; ``version`` is the response's ETag."""

    study_id: int
    version: str = Field(
        description="The ETag: send it as If-None-Match and an unchanged dashboard is a 304."
    )
    as_of: datetime = Field(description="When the server read it (UTC).")
    counts: LiveCountsOut
    labels: int = Field(description="Labels stored, all participants.")
    labels_last_minute: int = Field(description="Labels stored in the last 60 seconds.")
    labels_per_minute: float = Field(description="Mean labels per minute over the last 5 minutes.")
    max_participants: int | None = Field(description="The open link's seats (null: no link).")
    speed_threshold_ms: int = Field(description="The fast flag's threshold on the median.")
    gold_gate: float | None
    participants: list[LiveParticipantOut]
