"""``/api/participants``: a participant's own bracket, and any participant's tree."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse
from sqlalchemy.orm import Session

from app.core.errors import ForbiddenError
from app.core.json_types import IntParam
from app.http.deps import DbId, ResearcherDep, RuntimeDep, SessionDep, ViewerDep
from app.http.member_auth import InviteTokenDep, ParticipantDep
from app.http.urls import clip_url, image_url
from app.labelling import disagreement, gold_answers, participants, quality, study_link, trees
from app.labelling import service as labelling
from app.labelling.schemas import (
    BracketCellOut,
    BracketOut,
    GoldLabelOut,
    LabelIn,
    MeOut,
    NextMatchOut,
    PairOut,
    UndoOut,
)
from app.models import Participant
from app.recruiting import members
from app.recruiting import service as recruiting
from app.recruiting.schemas import OutcomeOut, WithdrawIn
from app.runtime import Runtime
from app.studies import service as studies
from app.studies.api import participant_out
from app.studies.schemas import ExclusionIn, ParticipantOut, ProgressOut
from engine.disagreement import MAX_PAIRS
from engine.treefile import tree_to_json

router = APIRouter(prefix="/participants", tags=["participants"])


def progress_out(progress: participants.Progress) -> ProgressOut:
    return ProgressOut(done=progress.done, total=progress.total)


@router.get("/me")
def me(person: ParticipantDep, session: SessionDep) -> MeOut:
    """The participant's study, instructions and progress."""
    study = studies.get_study(session, study_id=person.study_id)
    progress = participants.progress(session, participant=person)
    return MeOut(
        id=person.id,
        study_id=study.id,
        study_name=study.name,
        instructions=study.instructions,
        progress=progress_out(progress),
        finished=progress.finished,
        can_undo=labelling.can_undo(session, participant=person),
    )


@router.post(
    "/me/withdraw",
    responses={410: {"description": "They withdrew before, or their time is over."}},
)
def withdraw(body: WithdrawIn, person: ParticipantDep, session: SessionDep) -> OutcomeOut:
    """Withdraw from the study (``{"withdraw": true}``: it cannot be undone): the seat is
    freed, and the labels are kept but left out of trees, pooling, exports and the dataset.
    Returns the open link's code for it."""
    row = participants.get_participant(session, participant_id=person.id)
    return OutcomeOut.withdrawn(recruiting.withdraw(session, study_link.LINK, member=row))


@router.get(
    "/me/next-match",
    response_model=NextMatchOut,
    responses={204: {"description": "The bracket is finished."}},
)
async def next_match(token: InviteTokenDep, runtime: RuntimeDep) -> Response:
    """The next match to decide, or 204 when every match is decided."""
    # Hot path: authentication and one query in one worker-thread hop, with a session of
    # its own (held only while the thread runs), and the JSON written without a validation
    # layer (the body is built from typed rows; the schema is NextMatchOut).
    body = await runtime.run_hot(_next_match, runtime, token)
    return Response(status_code=204) if body is None else JSONResponse(body)


def _next_match(runtime: Runtime, token: str | None) -> dict[str, Any] | None:
    with runtime.engine.connect() as conn:
        person = members.participant_ref(conn, token=token)
        upcoming = labelling.next_match(conn, participant=person)
    return None if upcoming is None else next_match_body(person.study_id, upcoming)


def next_match_body(study_id: int, upcoming: labelling.NextMatch) -> dict[str, Any]:
    """The JSON of :class:`NextMatchOut`, built directly (the hot path skips pydantic)."""
    m, gold = upcoming.match, upcoming.gold
    shown = m if gold is None else gold
    marked = None if gold is None else gold.marked
    return {
        "match_id": m.id,
        "round": m.round,
        "n_rounds": upcoming.n_rounds,
        "match_number": upcoming.number,
        "matches_in_round": upcoming.in_round,
        "a": _side(study_id, shown.a, shown.a == marked, upcoming.clips),
        "b": _side(study_id, shown.b, shown.b == marked, upcoming.clips),
        "left": shown.left,
        "progress": {"done": upcoming.progress.done, "total": upcoming.progress.total},
        "gold": None if gold is None else {"item_id": gold.item_id, "prompt": gold.prompt},
        "allow_ties": upcoming.allow_ties and gold is None,
    }


def _side(
    study_id: int, candidate_id: int, marked: bool = False, clips: bool = False
) -> dict[str, Any]:
    return {
        "candidate_id": candidate_id,
        "image_url": image_url(study_id, candidate_id, marker=marked),
        "thumb_url": image_url(study_id, candidate_id, "thumb"),
        "clip_url": clip_url(study_id, candidate_id) if clips else None,
    }


@router.post(
    "/me/undo",
    responses={
        409: {
            "description": "No label to undo, or an answer after the bracket (a disagreement "
            "pair, the consistency check) is stored."
        },
        410: {"description": "The participant withdrew or ran out of time: answers are final."},
    },
)
def undo(person: ParticipantDep, session: SessionDep) -> UndoOut:
    """Take back the participant's latest label; 409 when there is none."""
    match = labelling.undo_label(session, participant=person)
    return UndoOut(
        match_id=match.id,
        round=match.round,
        progress=progress_out(participants.progress(session, participant=person)),
    )


@router.get("/me/bracket")
def bracket(person: ParticipantDep, session: SessionDep) -> BracketOut:
    """The whole bracket as decided so far, round by round (for the live bracket view)."""
    rounds = labelling.bracket_view(session, participant=person)
    return BracketOut(rounds=[[BracketCellOut(**vars(c)) for c in cells] for cells in rounds])


@router.get("/me/pairs")
def disagreement_pairs(person: ParticipantDep, session: SessionDep) -> list[PairOut]:
    """The participant's disagreement pairs, asked after the bracket (empty until it is
    finished, and when the study asks none)."""
    found = disagreement.pairs(session, participant=person)
    return [pair_out(person.study_id, p) for p in found]


@router.post(
    "/me/pairs/{position}/label",
    status_code=201,
    responses={
        200: {"description": "The same answer was already stored (idempotent).", "model": PairOut},
        410: {
            "description": "The participant withdrew, ran out of time, or was stopped by the "
            "gold gate: the study takes no more answers from them."
        },
        404: {"description": "No such pair for this participant (or the bracket is unfinished)."},
        409: {"description": "The pair is already answered the other way."},
        422: {"description": "The winner is not one of the pair."},
    },
)
def label_pair(
    position: Annotated[int, IntParam(ge=0, le=MAX_PAIRS)],
    body: LabelIn,
    person: ParticipantDep,
    session: SessionDep,
    response: Response,
) -> PairOut:
    """Store the participant's preferred candidate of a disagreement pair."""
    pair, created = disagreement.answer(
        session,
        participant=person,
        position=position,
        winner=body.winner,
        response_ms=body.response_ms,
    )
    if not created:
        response.status_code = 200
    return pair_out(person.study_id, pair)


def pair_out(study_id: int, pair: disagreement.PairView) -> PairOut:
    return PairOut(
        **vars(pair),
        left_image_url=image_url(study_id, pair.left),
        right_image_url=image_url(study_id, pair.right),
    )


@router.post(
    "/me/gold/{item_id}/label",
    status_code=201,
    response_model=GoldLabelOut,
    responses={
        200: {
            "description": "The same answer was already stored (idempotent).",
            "model": GoldLabelOut,
        },
        404: {"description": "No such gold item for this participant."},
        409: {"description": "The item is already answered the other way, or not due yet."},
        422: {"description": "The winner is not one of the pair."},
        410: {
            "description": "The participant withdrew, ran out of time, or was stopped by the "
            "gold gate: the study takes no more answers from them."
        },
    },
)
async def label_gold(
    item_id: DbId, body: LabelIn, token: InviteTokenDep, runtime: RuntimeDep
) -> Response:
    """Store the participant's answer to a gold item shown before a match (issue 28 §1);
    the answer carries the match to decide now."""
    # Hot path, as a label's (``matches_api.label_match``): one worker-thread hop with a
    # connection of its own, the answer stored in one short transaction, and the JSON
    # written without a validation layer (the schema is GoldLabelOut).
    created, out = await runtime.run_hot(_label_gold, runtime, token, item_id, body)
    return JSONResponse(out, status_code=201 if created else 200)


def _label_gold(
    runtime: Runtime, token: str | None, item_id: int, body: LabelIn
) -> tuple[bool, dict[str, Any]]:
    with runtime.engine.connect() as conn:
        person = members.participant_ref(conn, token=token)
        answered = gold_answers.answer(
            conn,
            participant_id=person.id,
            item_id=item_id,
            winner=body.winner,
            response_ms=body.response_ms,
        )
        upcoming = labelling.next_match(conn, participant=person, done=answered.done)
    if answered.created:  # the gate reads their standing with this answer
        quality.gate_after_answer(runtime.sessions, person, answered.standing, answered.gate)
    out = {
        "item_id": item_id,
        "winner": body.winner,
        "created": answered.created,
        "next": None if upcoming is None else next_match_body(person.study_id, upcoming),
    }
    return answered.created, out


@router.put("/{participant_id}/exclusion")
def set_exclusion(
    participant_id: DbId, body: ExclusionIn, request: Request, session: SessionDep, _: ResearcherDep
) -> ParticipantOut:
    """Exclude a participant from pooling and exports, or include them again (issue 28 §1);
    their labels are never deleted."""
    person = participants.set_exclusion(
        session, participant_id=participant_id, excluded=body.excluded, reason=body.reason
    )
    return _participant_out(request, session, person)


def _participant_out(request: Request, session: Session, person: Participant) -> ParticipantOut:
    link = recruiting.settings(session, study_link.LINK, person.study_id)
    return participant_out(
        request, person, participants.progress(session, participant=person), link
    )


@router.get("/{participant_id}")
def get_participant(
    participant_id: DbId, request: Request, session: SessionDep, _: ResearcherDep
) -> ParticipantOut:
    person = participants.get_participant(session, participant_id=participant_id)
    return _participant_out(request, session, person)


@router.get("/{participant_id}/tree")
def participant_tree(
    participant_id: DbId, session: SessionDep, viewer: ViewerDep
) -> dict[str, Any]:
    """The participant's Human Preference Tree as an ``acv.tree/1`` document (researcher,
    or that participant); 409 until the bracket is finished."""
    if not viewer.researcher and (
        viewer.participant is None or viewer.participant.id != participant_id
    ):
        raise ForbiddenError("a participant may only see their own tree")
    return tree_to_json(trees.participant_tree(session, participant_id=participant_id))
