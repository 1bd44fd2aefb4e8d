"""Bodies of a participant's practice API (``/api/participants/me/practice``)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from engine.practice import PairKind, PracticePair, Side


class PracticePairOut(BaseModel):
    """A practice pair, before the bracket: nothing in it tells an instructed pair's answer."""

    position: int = Field(description="Its place in the participant's practice, from 0.")
    total: int = Field(description="The participant's practice pairs.")
    kind: PairKind = Field(
        description="instructed: choose the picture with the marker (a right answer); "
        "preference: no right answer."
    )
    prompt: str = Field(description="What the pair asks.")
    left_url: str = Field(description="The picture on the left.")
    right_url: str = Field(description="The picture on the right.")


class PracticeAnswerIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    side: Side = Field(description="The picture chosen.")


class PracticeFeedbackOut(BaseModel):
    """The feedback on a practice answer; nothing is stored."""

    position: int
    kind: PairKind
    correct: bool | None = Field(description="Right or wrong; null: there is no right answer.")
    marker: Side | None = Field(description="Where the marker was (instructed pairs).")
    feedback: str = Field(description="A sentence for the participant.")


def practice_image_url(api_path: str, position: int, side: Side) -> str:
    """Where the picture on ``side`` of the caller's practice pair ``position`` is served by
    the practice API at ``api_path`` (the URL says nothing of the marker)."""
    return f"{api_path}/{position}/image?side={side}"


def practice_pair_out(
    pair: PracticePair, total: int, *, api_path: str, prompt: str
) -> PracticePairOut:
    """``pair`` as a practice API shows it: ``prompt`` asked, pictures under ``api_path``."""
    return PracticePairOut(
        position=pair.position,
        total=total,
        kind=pair.kind,
        prompt=prompt,
        left_url=practice_image_url(api_path, pair.position, "left"),
        right_url=practice_image_url(api_path, pair.position, "right"),
    )
