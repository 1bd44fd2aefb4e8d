"""``/api/evaluators/me/practice``: an evaluator's practice pairs before their first pair,
their pictures and the feedback on an answer (:mod:`app.evaluations.practice`, the bodies of
a study's practice API). Nothing is stored."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter
from fastapi.responses import FileResponse

from app.core.json_types import IntParam
from app.evaluations import practice
from app.http.deps import SessionDep, SettingsDep
from app.http.member_auth import EvaluatorDep
from app.labelling import practice_schemas
from app.labelling.practice import PROMPTS, picture
from app.labelling.practice_schemas import PracticeAnswerIn, PracticeFeedbackOut, PracticePairOut
from app.studies.images import MEDIA_TYPE
from engine.practice import MAX_PRACTICE_PAIRS, PracticePair, Side

router = APIRouter(prefix="/evaluators/me/practice", tags=["evaluators"])
PATH = "/api" + router.prefix
Position = Annotated[int, IntParam(ge=0, le=MAX_PRACTICE_PAIRS - 1)]


def practice_image_url(position: int, side: Side) -> str:
    """Where the picture on ``side`` of the caller's practice pair ``position`` is served."""
    return practice_schemas.practice_image_url(PATH, position, side)


def pair_out(pair: PracticePair, total: int) -> PracticePairOut:
    return practice_schemas.practice_pair_out(pair, total, api_path=PATH, prompt=PROMPTS[pair.kind])


@router.get("")
def practice_pairs(
    person: EvaluatorDep, session: SessionDep, settings: SettingsDep
) -> list[PracticePairOut]:
    """The evaluator's practice pairs, in order: empty when the evaluation asks none and
    once they have an answer."""
    found = practice.practice(session, evaluator=person, data_dir=settings.data_dir)
    return [pair_out(p, len(found.pairs)) for p in found.pairs]


@router.get(
    "/{position}/image",
    response_class=FileResponse,
    responses={200: {"content": {MEDIA_TYPE: {}}}},
)
def practice_image(
    position: Position,
    side: Side,
    person: EvaluatorDep,
    session: SessionDep,
    settings: SettingsDep,
) -> FileResponse:
    """The picture on ``side`` of a practice pair (with the marker where it has one)."""
    found = practice.practice(session, evaluator=person, data_dir=settings.data_dir)
    path = picture(found, position=position, side=side)
    # One URL shows each evaluator their own pair: revalidate rather than reuse.
    return FileResponse(path, media_type=MEDIA_TYPE, headers={"Cache-Control": "private, no-cache"})


@router.post(
    "/{position}/answer",
    responses={404: {"description": "No such practice pair for this evaluator."}},
)
def answer(
    position: Position,
    body: PracticeAnswerIn,
    person: EvaluatorDep,
    session: SessionDep,
    settings: SettingsDep,
) -> PracticeFeedbackOut:
    """The feedback on choosing ``side`` of a practice pair; nothing is stored, so asking
    again gives the same answer."""
    found = practice.practice(session, evaluator=person, data_dir=settings.data_dir)
    pair = found.pair(position)
    said = practice.said(pair, body.side)
    return PracticeFeedbackOut(
        position=position,
        kind=pair.kind,
        correct=said.correct,
        marker=said.marker,
        feedback=said.message,
    )
