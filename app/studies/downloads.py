"""Researcher downloads as files: one participant's ``acv.tree/1`` document, or a zip of all
finished participants' trees. (Labels CSV: ``GET /api/studies/{id}/labels.csv``.)"""

from __future__ import annotations

import io
import zipfile

from fastapi import APIRouter, Response

from app.core.errors import NotFoundError
from app.http.deps import DbId, SessionDep
from app.http.files import attachment
from app.http.guards import ResearcherPage
from app.http.rendering import PageRoute
from app.labelling import participants, trees
from app.studies.schemas import IncludeExcluded
from engine.treefile import dumps

router = APIRouter(route_class=PageRoute, include_in_schema=False, dependencies=[ResearcherPage])


def tree_filename(study_id: int, participant_id: int) -> str:
    return f"study-{study_id}-participant-{participant_id}.acv-tree.json"


@router.get("/studies/{study_id}/participants/{participant_id}/tree.json")
def participant_tree(study_id: DbId, participant_id: DbId, session: SessionDep) -> Response:
    """A finished participant's Human Preference Tree as an ``acv.tree/1`` file."""
    person = participants.get_participant(session, participant_id=participant_id)
    if person.study_id != study_id:
        raise NotFoundError(f"participant {participant_id} is not in study {study_id}")
    doc = trees.participant_tree(session, participant_id=participant_id)
    return attachment(dumps(doc), "application/json", tree_filename(study_id, participant_id))


@router.get("/studies/{study_id}/trees.zip")
def all_trees(
    study_id: DbId, session: SessionDep, include_excluded: IncludeExcluded = False
) -> Response:
    """Every finished participant's tree, one ``acv.tree/1`` file each, in a zip (excluded
    participants' only on request)."""
    found = trees.study_trees(session, study_id=study_id, include_excluded=include_excluded)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for pid, doc in found:
            archive.writestr(tree_filename(study_id, pid), dumps(doc))
    return attachment(buffer.getvalue(), "application/zip", f"study-{study_id}-trees.zip")
