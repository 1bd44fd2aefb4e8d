"""``/api/participants/me/practice``: a participant's practice pairs before the bracket, their
pictures and the feedback on an answer (:mod:`app.labelling.practice`). Nothing is stored."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter
from fastapi.responses import FileResponse

from app.core.json_types import IntParam
from app.http.deps import SessionDep, SettingsDep
from app.http.member_auth import ParticipantDep
from app.labelling import practice, practice_schemas
from app.labelling.practice_schemas import PracticeAnswerIn, PracticeFeedbackOut, PracticePairOut
from app.studies.images import MEDIA_TYPE
from engine.practice import MAX_PRACTICE_PAIRS, PracticePair, Side

router = APIRouter(prefix="/participants/me/practice", tags=["participants"])
PATH = "/api" + router.prefix
Position = Annotated[int, IntParam(ge=0, le=MAX_PRACTICE_PAIRS - 1)]


def practice_image_url(position: int, side: Side) -> str:
    """Where the picture on ``side`` of the caller's practice pair ``position`` is served."""
    return practice_schemas.practice_image_url(PATH, position, side)


def pair_out(pair: PracticePair, total: int) -> PracticePairOut:
    return practice_schemas.practice_pair_out(
        pair, total, api_path=PATH, prompt=practice.PROMPTS[pair.kind]
    )


@router.get("")
def practice_pairs(
    person: ParticipantDep, session: SessionDep, settings: SettingsDep
) -> list[PracticePairOut]:
    """The participant's practice pairs, in order: empty when the study asks none and once
    they have a label."""
    found = practice.practice(session, participant=person, images_dir=settings.images_dir)
    return [pair_out(p, len(found.pairs)) for p in found.pairs]


@router.get(
    "/{position}/image",
    response_class=FileResponse,
    responses={200: {"content": {MEDIA_TYPE: {}}}},
)
def practice_image(
    position: Position,
    side: Side,
    person: ParticipantDep,
    session: SessionDep,
    settings: SettingsDep,
) -> FileResponse:
    """The picture on ``side`` of a practice pair (with the marker where it has one)."""
    found = practice.practice(session, participant=person, images_dir=settings.images_dir)
    path = practice.picture(found, position=position, side=side)
    # One URL shows each participant their own pair: revalidate rather than reuse.
    return FileResponse(path, media_type=MEDIA_TYPE, headers={"Cache-Control": "private, no-cache"})


@router.post(
    "/{position}/answer",
    responses={404: {"description": "No such practice pair for this participant."}},
)
def answer(
    position: Position,
    body: PracticeAnswerIn,
    person: ParticipantDep,
    session: SessionDep,
    settings: SettingsDep,
) -> PracticeFeedbackOut:
    """The feedback on choosing ``side`` of a practice pair; nothing is stored, so asking
    again gives the same answer."""
    found = practice.practice(session, participant=person, images_dir=settings.images_dir)
    pair = found.pair(position)
    said = practice.feedback(pair, body.side)
    return PracticeFeedbackOut(
        position=position,
        kind=pair.kind,
        correct=said.correct,
        marker=said.marker,
        feedback=said.message,
    )
