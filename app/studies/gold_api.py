"""``/api/studies/{id}/gold``: a study's gold items (issue 28 §1), pairs with an objective
answer shown among the bracket's matches. Researcher only."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Response
from pydantic import BaseModel, ConfigDict, Field

from app.core.json_types import JsonInt, UtcDatetime
from app.http.deps import DbId, ResearcherDep, SessionDep
from app.studies import gold

router = APIRouter(prefix="/studies", tags=["gold"])

_CandidateId = Field(ge=0, le=2**31 - 1)


class GoldItemIn(BaseModel):
    """A gold item: two of the study's candidates and the right answer. ``instructed``
    shows ``answer`` with a marker ("choose the picture with the marker")."""

    model_config = ConfigDict(extra="forbid")

    kind: Literal["pair", "instructed"] = "pair"
    a: JsonInt = _CandidateId
    b: JsonInt = _CandidateId
    answer: JsonInt = _CandidateId


class GoldItemOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    study_id: int
    kind: str
    a: int
    b: int
    answer: int
    created_at: UtcDatetime


@router.get("/{study_id}/gold")
def list_gold(study_id: DbId, session: SessionDep, _: ResearcherDep) -> list[GoldItemOut]:
    """The study's gold items, oldest first."""
    return [
        GoldItemOut.model_validate(item) for item in gold.list_items(session, study_id=study_id)
    ]


@router.post(
    "/{study_id}/gold",
    status_code=201,
    responses={422: {"description": "A candidate of another study, a == b, or a bad answer."}},
)
def add_gold(
    study_id: DbId, body: GoldItemIn, session: SessionDep, _: ResearcherDep
) -> GoldItemOut:
    """Add a gold item; participants who join from now on get it, at seeded positions
    among their bracket's matches."""
    item = gold.add_item(
        session, study_id=study_id, kind=body.kind, a=body.a, b=body.b, answer=body.answer
    )
    return GoldItemOut.model_validate(item)


@router.delete(
    "/{study_id}/gold/{item_id}",
    status_code=204,
    responses={409: {"description": "Somebody answered it: it is kept."}},
)
def delete_gold(study_id: DbId, item_id: DbId, session: SessionDep, _: ResearcherDep) -> Response:
    """Remove a gold item nobody has answered yet."""
    gold.delete_item(session, study_id=study_id, item_id=item_id)
    return Response(status_code=204)
