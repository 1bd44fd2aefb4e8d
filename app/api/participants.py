"""``/api/participants``: a participant's own bracket, and any participant's tree."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.api.deps import (
    DbId,
    InviteTokenDep,
    ParticipantDep,
    ResearcherDep,
    SessionDep,
    ViewerDep,
)
from app.api.schemas import (
    BracketCellOut,
    BracketOut,
    MatchSide,
    MeOut,
    NextMatchOut,
    ParticipantOut,
    ProgressOut,
    UndoOut,
)
from app.api.studies import participant_out
from app.api.urls import image_url
from app.services import auth, labelling, participants, studies, trees
from app.services.errors import ForbiddenError
from engine.treefile import tree_to_json

router = APIRouter(prefix="/participants", tags=["participants"])


def progress_out(progress: participants.Progress) -> ProgressOut:
    return ProgressOut(done=progress.done, total=progress.total)


@router.get("/me")
def me(person: ParticipantDep, session: SessionDep) -> MeOut:
    """The participant's study, instructions and progress."""
    study = studies.get_study(session, study_id=person.study_id)
    progress = participants.progress(session, participant=person)
    return MeOut(id=person.id, study_id=study.id, study_name=study.name,
                 instructions=study.instructions, progress=progress_out(progress),
                 finished=progress.finished,
                 can_undo=labelling.can_undo(session, participant=person))


@router.get("/me/next-match", response_model=NextMatchOut,
            responses={204: {"description": "The bracket is finished."}})
async def next_match(token: InviteTokenDep, session: SessionDep) -> NextMatchOut | Response:
    """The next match to decide, or 204 when every match is decided."""
    # Hot path: authentication and the query in one worker-thread hop, and the response
    # validated on the event loop (a sync handler would cost three hops).
    return await run_in_threadpool(_next_match, session, token)


def _next_match(session: Session, token: str | None) -> NextMatchOut | Response:
    person = auth.participant_by_token(session, token=token)
    upcoming = labelling.next_match(session, participant=person)
    if upcoming is None:
        return Response(status_code=204)
    m, sid = upcoming.match, person.study_id
    return NextMatchOut(
        match_id=m.id, round=m.round, n_rounds=upcoming.n_rounds,
        match_number=upcoming.number, matches_in_round=upcoming.in_round,
        a=MatchSide(candidate_id=m.a, image_url=image_url(sid, m.a),
                    thumb_url=image_url(sid, m.a, "thumb")),
        b=MatchSide(candidate_id=m.b, image_url=image_url(sid, m.b),
                    thumb_url=image_url(sid, m.b, "thumb")),
        progress=progress_out(upcoming.progress))


@router.post("/me/undo")
def undo(person: ParticipantDep, session: SessionDep) -> UndoOut:
    """Take back the participant's latest label; 409 when there is none."""
    match = labelling.undo_label(session, participant=person)
    return UndoOut(match_id=match.id, round=match.round,
                   progress=progress_out(participants.progress(session, participant=person)))


@router.get("/me/bracket")
def bracket(person: ParticipantDep, session: SessionDep) -> BracketOut:
    """The whole bracket as decided so far, round by round (for the live bracket view)."""
    rounds = labelling.bracket_view(session, participant=person)
    return BracketOut(rounds=[[BracketCellOut(**vars(c)) for c in cells] for cells in rounds])


@router.get("/{participant_id}")
def get_participant(participant_id: DbId, request: Request, session: SessionDep,
                    _: ResearcherDep) -> ParticipantOut:
    person = participants.get_participant(session, participant_id=participant_id)
    return participant_out(request, person, participants.progress(session, participant=person))


@router.get("/{participant_id}/tree")
def participant_tree(participant_id: DbId, session: SessionDep,
                     viewer: ViewerDep) -> dict[str, Any]:
    """The participant's Human Preference Tree as an ``acv.tree/1`` document (researcher,
    or that participant); 409 until the bracket is finished."""
    if not viewer.researcher and viewer.participant.id != participant_id:
        raise ForbiddenError("a participant may only see their own tree")
    return tree_to_json(trees.participant_tree(session, participant_id=participant_id))
