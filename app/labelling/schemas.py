"""Bodies of a participant's own API (``/api/participants/me``, ``/api/matches``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from app.core.json_types import JsonInt
from app.labelling.service import MAX_RESPONSE_MS, BracketCell
from app.studies.schemas import ProgressOut


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


@dataclass(frozen=True)
class BracketCellOut(BracketCell):
    """One slot of the live bracket (the service's record)."""


class BracketOut(BaseModel):
    rounds: list[list[BracketCellOut]]
