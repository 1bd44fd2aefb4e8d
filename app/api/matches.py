"""``/api/matches``: storing a participant's decision."""

from __future__ import annotations

from fastapi import APIRouter, Response
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from app.api.deps import DbId, InviteTokenDep, ParticipantDep, SessionDep
from app.api.participants import progress_out
from app.api.schemas import LabelIn, LabelOut, UndoOut
from app.services import auth, labelling, participants

router = APIRouter(prefix="/matches", tags=["matches"])


@router.post("/{match_id}/label", status_code=201, responses={
    200: {"description": "The same label was already stored (idempotent)."},
    404: {"description": "No such match among this participant's."},
    409: {"description": "The match is already decided the other way."},
    422: {"description": "The winner did not play this match."}})
async def label_match(match_id: DbId, body: LabelIn, token: InviteTokenDep,
                      session: SessionDep, response: Response) -> LabelOut:
    """Store the participant's preferred candidate of a match."""
    # Hot path: one worker-thread hop, as in ``next-match``.
    result = await run_in_threadpool(_label, session, token, match_id, body)
    if not result.created:
        response.status_code = 200
    return LabelOut(match_id=result.match.id, winner=result.label.winner,
                    created=result.created, progress=progress_out(result.progress),
                    finished=result.progress.finished)


def _label(session: Session, token: str | None, match_id: int,
           body: LabelIn) -> labelling.LabelResult:
    person = auth.participant_by_token(session, token=token)
    return labelling.submit_label(session, participant=person, match_id=match_id,
                                  winner=body.winner, response_ms=body.response_ms)


@router.delete("/{match_id}/label", responses={
    404: {"description": "No such match among this participant's."},
    409: {"description": "Not labelled, or a later match already depends on it."}})
def undo_label(match_id: DbId, person: ParticipantDep, session: SessionDep) -> UndoOut:
    """Take back the label of one of the participant's matches, while the next-round match
    containing its winner is undecided."""
    match = labelling.undo_label(session, participant=person, match_id=match_id)
    return UndoOut(match_id=match.id, round=match.round,
                   progress=progress_out(participants.progress(session, participant=person)))
