"""Bodies of a participant's own API (``/api/participants/me``, ``/api/matches``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool

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
    clip_url: str | None = Field(
        None,
        description="Its motion clip, where the study has clips and both of this pair's are "
        'rendered (label the pair with stimulus "clip" once one has played); null: stills.',
    )


class GoldDueOut(BaseModel):
    """A gold item to answer before the match (issue 28 §1): not part of the bracket."""

    item_id: int = Field(description="Answer it at /api/participants/me/gold/{item_id}/label.")
    prompt: str | None = Field(
        description='What an instructed item asks ("choose the picture with the marker"); '
        "null for a pair, asked like any match."
    )


class NextMatchOut(BaseModel):
    """Round ``round`` of ``n_rounds``, match ``match_number`` of ``matches_in_round``.
    While ``gold`` is set, ``a``, ``b`` and ``left`` are the gold item's pair, shown before
    the match ``match_id``."""

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
    gold: GoldDueOut | None = None
    allow_ties: bool = Field(False, description='Whether "can\'t tell" is an answer here.')


class LabelIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    winner: JsonInt = Field(ge=0, le=2**31 - 1, description="The preferred candidate's id.")
    response_ms: Annotated[JsonInt, Field(ge=0, le=MAX_RESPONSE_MS)] | None = Field(
        None, description="Time the participant took; estimated by the server when absent."
    )


class MatchLabelIn(LabelIn):
    """A decision of a bracket match: the preferred candidate, or ``tie`` ("can't tell",
    in studies that allow it: a seeded coin then advances one of the two)."""

    winner: JsonInt | None = Field(  # type: ignore[assignment]  # optional with a tie
        None, ge=0, le=2**31 - 1, description="The preferred candidate's id; omit with tie."
    )
    tie: StrictBool = Field(False, description="The participant cannot tell.")
    stimulus: Literal["still", "clip"] = Field(
        "still",
        description='What the page showed: "still" (the pictures) or "clip" (the pair\'s '
        "clips; refused where they are not rendered).",
    )


class LabelOut(BaseModel):
    match_id: int
    winner: int = Field(description="Who advances: the choice, or the coin's after a tie.")
    tie: bool = False
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


class GoldLabelOut(BaseModel):
    """A stored answer to a gold item, with the match to decide now."""

    item_id: int
    winner: int
    created: bool
    next: NextMatchOut | None


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


class ShareConsentIn(BaseModel):
    """Whether the participant agrees that their labels may be shared in a public dataset,
    under a pseudonym (issue 29 §4)."""

    model_config = ConfigDict(extra="forbid")

    share: StrictBool = Field(description="true: agree; false: do not (the default).")


class ShareConsentOut(BaseModel):
    share: bool = Field(description="The participant's choice as now stored.")
