"""``/api/matches``: storing a participant's decision."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse

from app.http.deps import DbId, RuntimeDep, SessionDep
from app.http.member_auth import InviteTokenDep, ParticipantDep
from app.labelling import participants
from app.labelling import service as labelling
from app.labelling.api import next_match_body, progress_out
from app.labelling.schemas import LabelOut, MatchLabelIn, UndoOut
from app.recruiting import members
from app.runtime import Runtime

router = APIRouter(prefix="/matches", tags=["matches"])


@router.post(
    "/{match_id}/label",
    status_code=201,
    response_model=LabelOut,
    responses={
        200: {"description": "The same label was already stored (idempotent).", "model": LabelOut},
        404: {"description": "No such match among this participant's."},
        409: {"description": "The match is already decided the other way."},
        410: {
            "description": "The participant withdrew, ran out of time, or was stopped by the "
            "gold gate: the study takes no more labels from them."
        },
        422: {
            "description": "The winner did not play this match, a tie where the study "
            'does not allow "can\'t tell", or stimulus "clip" where the pair has no clips.'
        },
    },
)
async def label_match(
    match_id: DbId, body: MatchLabelIn, token: InviteTokenDep, runtime: RuntimeDep
) -> Response:
    """Store the participant's preferred candidate of a match, or ``{"tie": true}`` ("can't
    tell", where the study allows it). The answer carries the next match to decide
    (``next``, ``null`` once the bracket is finished), so a participant needs one round trip
    per decision."""
    # Hot path: one worker-thread hop with a session of its own, as in ``next-match``.
    result, study_id = await runtime.run_hot(_label, runtime, token, match_id, body)
    return JSONResponse(label_body(result, study_id), status_code=201 if result.created else 200)


def _label(
    runtime: Runtime, token: str | None, match_id: int, body: MatchLabelIn
) -> tuple[labelling.LabelResult, int]:
    with runtime.engine.connect() as conn:
        person = members.participant_ref(conn, token=token)
        result = labelling.submit_label(
            conn,
            participant=person,
            match_id=match_id,
            winner=body.winner,
            tie=body.tie,
            response_ms=body.response_ms,
            with_next=True,
            stimulus=body.stimulus,
        )
    return result, person.study_id


def label_body(result: labelling.LabelResult, study_id: int) -> dict[str, Any]:
    """The JSON of :class:`LabelOut`, built directly (the hot path skips pydantic)."""
    return {
        "match_id": result.match_id,
        "winner": result.winner,
        "tie": result.tie,
        "created": result.created,
        "progress": {"done": result.progress.done, "total": result.progress.total},
        "finished": result.progress.finished,
        "next": None if result.next is None else next_match_body(study_id, result.next),
    }


@router.delete(
    "/{match_id}/label",
    responses={
        404: {"description": "No such match among this participant's."},
        409: {
            "description": "Not labelled, a later match already depends on it, or an answer "
            "after the bracket (a disagreement pair, the consistency check) is stored."
        },
        410: {"description": "The participant withdrew or ran out of time: answers are final."},
    },
)
def undo_label(match_id: DbId, person: ParticipantDep, session: SessionDep) -> UndoOut:
    """Take back the label of one of the participant's matches, while the next-round match
    containing its winner is undecided."""
    match = labelling.undo_label(session, participant=person, match_id=match_id)
    return UndoOut(
        match_id=match.id,
        round=match.round,
        progress=progress_out(participants.progress(session, participant=person)),
    )
