"""``/api/evaluators/me``: an evaluator's side of an agent evaluation, by their invite token.

Blind by construction: a pair is named only by its opaque ``key``, its pictures are served
under that key and a side (``left``/``right``), only to the evaluator it belongs to, with no
ETag or Last-Modified (a shared file's validator would tell two pairs showing the same
agent apart from the rest). No run id, slot, arm, seed or checkpoint is in any answer here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from fastapi import APIRouter, Response
from fastapi import Path as PathParam
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.evaluations import crowd, evaluators, gold, reminder
from app.evaluations import service as evaluations
from app.evaluations.schemas import AnswerIn, PairOut
from app.evaluations.service import StimulusKind
from app.evaluations.stimuli import stimuli_dir
from app.http.deps import SessionDep, SettingsDep
from app.http.member_auth import EvaluatorDep
from app.labelling.schemas import ShareConsentIn, ShareConsentOut
from app.models import EvaluationPair, EvaluationStimulus, Evaluator, utcnow
from app.recruiting import seats
from app.recruiting import service as recruiting
from app.recruiting.schemas import OutcomeOut, WithdrawIn
from app.studies.images import MEDIA_TYPE as IMAGE_TYPE
from app.studies.images import image_file
from engine.render.image import with_marker

router = APIRouter(prefix="/evaluators/me", tags=["evaluators"])

Side = Literal["left", "right"]
PairKey = Annotated[str, PathParam(min_length=1, max_length=32, pattern=r"^[A-Za-z0-9_-]+$")]
Place = Literal["first", "second", "third", "fourth"]  # reminder.PLACES
MEDIA_TYPES = {"still": "image/jpeg", "clip": "image/webp"}
#: The pictures of a pair never change: the browser may keep them, for this evaluator only.
CACHE = "private, max-age=86400, immutable"


class EvaluatorMeOut(OutcomeOut):
    """What the evaluator is asked, how far they are, and what became of them (with the open
    link's code for it)."""

    question: str
    instructions: str
    done: int
    total: int
    finished: bool


@router.get("")
def me(person: EvaluatorDep, session: SessionDep) -> EvaluatorMeOut:
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    progress = evaluators.progress(session, evaluator_id=person.id)
    session.refresh(person)
    result, shown = recruiting.outcome(session, crowd.LINK, member=person)
    return EvaluatorMeOut(
        question=evaluation.question,
        instructions=evaluation.instructions,
        done=progress.done,
        total=progress.total,
        finished=progress.finished,
        outcome=result.name,
        code=shown.code if shown else None,
        redirect_url=shown.redirect_url if shown else None,
    )


@router.post(
    "/withdraw",
    responses={410: {"description": "They withdrew before, or their time is over."}},
)
def withdraw(body: WithdrawIn, person: EvaluatorDep, session: SessionDep) -> OutcomeOut:
    """Withdraw from the evaluation (``{"withdraw": true}``: it cannot be undone): the seat is
    freed, and the answers are kept but left out of the result and the export. Returns the
    open link's code for it."""
    return OutcomeOut.withdrawn(recruiting.withdraw(session, crowd.LINK, member=person))


@router.get(
    "/pairs/next",
    response_model=PairOut,
    responses={204: {"description": "Every pair is answered."}},
)
def next_pair(person: EvaluatorDep, session: SessionDep) -> PairOut | Response:
    """The first pair still to answer (204 once none is left)."""
    seats.check_can_act(person, utcnow())
    pair = evaluators.next_pair(session, evaluator_id=person.id)
    if pair is None:
        return Response(status_code=204)
    return pair_out(session, person, pair)


def pair_out(session: Session, person: Evaluator, pair: EvaluationPair) -> PairOut:
    """A pair as the evaluator sees it: its key, its place, and its pictures' URLs."""
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    gold_pair = pair.gold_answer is not None  # an instructed gold pair: stills, the marker
    kind = evaluators.shown_kind(evaluation, pair)
    total = evaluators.progress(session, evaluator_id=person.id).total
    return PairOut(
        key=pair.key,
        position=pair.position,
        total=total,
        question=gold.INSTRUCTED_PROMPT if gold_pair else evaluation.question,
        left=_side(pair.key, "left", kind),
        right=_side(pair.key, "right", kind),
        reminder=reminder.urls(session, evaluation),
    )


def _side(key: str, side: Side, kind: StimulusKind) -> dict[str, str]:
    base = f"/api/evaluators/me/pairs/{key}/{side}"
    sides = {"still": f"{base}/still"}
    if kind == "clip":
        sides["clip"] = f"{base}/clip"
    return sides


@router.post("/pairs/{key}")
def answer_pair(
    key: PairKey, body: AnswerIn, person: EvaluatorDep, session: SessionDep
) -> EvaluatorMeOut:
    """Answer one pair: ``left``, ``right`` or ``tie`` (can't tell). Once; the same answer
    again is accepted, another is a 409."""
    seats.check_can_act(person, utcnow())
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    shown = evaluators.Shown(
        stimulus=body.stimulus,
        reminder=reminder.shown(session, evaluation),
    )
    evaluators.answer(
        session,
        evaluator=person,
        key=key,
        choice=body.choice,
        response_ms=body.response_ms,
        shown=shown,
    )
    return me(person, session)


@router.get(
    "/pairs/{key}/{side}/{kind}",
    response_class=Response,
    responses={200: {"content": {"image/jpeg": {}, "image/webp": {}}}},
)
def pair_picture(
    key: PairKey,
    side: Side,
    kind: StimulusKind,
    person: EvaluatorDep,
    session: SessionDep,
    settings: SettingsDep,
) -> Response:
    """One side of one of the evaluator's pairs: its still (JPEG) or clip (animated WebP); a
    gold pair's stills only, the marker drawn on its answer's."""
    pair = evaluators.pair_by_key(session, evaluator_id=person.id, key=key)
    slot, window = (
        (pair.a, pair.window_a) if (side == "left") == pair.a_left else (pair.b, pair.window_b)
    )
    stimulus = session.get(EvaluationStimulus, (person.evaluation_id, slot, window))
    path = (
        None
        if stimulus is None
        else (stimulus.clip_path if kind == "clip" else stimulus.still_path)
    )
    if path is None or (pair.gold_answer is not None and kind == "clip"):
        raise NotFoundError(f"no {kind} of this pair yet")
    file = stimuli_dir(settings.data_dir) / Path(path)
    if not file.is_file():  # a data dir restored without its stimuli, say
        raise NotFoundError(f"the {kind} of this pair is missing on disk")
    data = file.read_bytes()
    if pair.gold_answer == slot:
        data = with_marker(data)
    return Response(data, media_type=MEDIA_TYPES[kind], headers={"Cache-Control": CACHE})


@router.get(
    "/reminder/{place}",
    response_class=Response,
    responses={200: {"content": {IMAGE_TYPE: {}}}},
)
def reminder_picture(
    place: Place, person: EvaluatorDep, session: SessionDep, settings: SettingsDep
) -> Response:
    """The reminder's picture at ``place`` (``first``: the advisor's choice in the final),
    small; 404 where the evaluation shows no reminder."""
    evaluation = evaluations.get_evaluation(session, evaluation_id=person.evaluation_id)
    found = reminder.pictures(session, evaluation)
    index = reminder.PLACES.index(place)
    if index >= len(found):
        raise NotFoundError("no such reminder picture")
    path = image_file(settings.data_dir, found[index].thumb_path)
    if not path.is_file():
        raise NotFoundError("the reminder picture is missing on disk")
    return Response(path.read_bytes(), media_type=IMAGE_TYPE, headers={"Cache-Control": CACHE})


@router.put(
    "/share-consent",
    responses={410: {"description": "They withdrew: their answers are never shared."}},
)
def share_consent(
    body: ShareConsentIn, person: EvaluatorDep, session: SessionDep
) -> ShareConsentOut:
    """Agree, or no longer agree, that your answers may be shared in a public dataset under
    a pseudonym; off unless you agree. An export made afterwards follows your latest choice."""
    return ShareConsentOut(share=evaluators.set_share_consent(session, person, share=body.share))
