"""``/api/studies``: create and inspect studies, their candidates, participants and exports."""

from __future__ import annotations

from dataclasses import asdict
from typing import Annotated, Any

from fastapi import APIRouter, Request, Response
from fastapi.responses import FileResponse
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.core.json_types import IntParam
from app.core.rows import from_row
from app.http.deps import (
    CandidateId,
    DbId,
    ResearcherDep,
    RuntimeDep,
    SessionDep,
    SettingsDep,
    Viewer,
    ViewerDep,
)
from app.http.files import attachment
from app.http.urls import clip_url, image_url, invite_url
from app.labelling import participants, study_link, trees
from app.models import Candidate, OpenLink, Participant, utcnow
from app.recruiting import seats
from app.recruiting import service as recruiting
from app.runs import power
from app.runs.experiments import DEFAULT_SEEDS, MAX_SEEDS, MIN_SEEDS
from app.studies import service as studies
from app.studies.images import MEDIA_TYPE, ImageSize, image_file
from app.studies.schemas import (
    AdvicePowerOut,
    CandidateOut,
    IncludeExcluded,
    ParticipantBatchCreate,
    ParticipantCreate,
    ParticipantCreated,
    ParticipantOut,
    ProgressOut,
    StudyCreate,
    StudyOut,
)
from engine.evaluation.clips import CLIP_MEDIA_TYPE
from engine.render.image import with_marker
from engine.treefile import tree_to_json

router = APIRouter(prefix="/studies", tags=["studies"])


@router.post("", status_code=201)
def create_study(
    body: StudyCreate, session: SessionDep, runtime: RuntimeDep, _: ResearcherDep
) -> StudyOut:
    """Create a study; its candidates are sampled and rendered in the background
    (``status`` goes from ``preparing`` to ``ready``, or ``failed`` with ``error``)."""
    study = studies.create_study(session, spec=body.spec())
    runtime.prepare_later(study.id)
    return StudyOut.model_validate(study)


@router.get("")
def list_studies(session: SessionDep, _: ResearcherDep) -> list[StudyOut]:
    return [StudyOut.model_validate(s) for s in studies.list_studies(session)]


@router.get("/{study_id}")
def get_study(study_id: DbId, session: SessionDep, _: ResearcherDep) -> StudyOut:
    return StudyOut.model_validate(studies.get_study(session, study_id=study_id))


@router.get("/{study_id}/power")
def study_power(
    study_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    seeds: Annotated[int, IntParam(ge=MIN_SEEDS, le=MAX_SEEDS)] = DEFAULT_SEEDS,
) -> list[AdvicePowerOut]:
    """Can this bracket tell? Per finished participant: the matches that can tell whether an
    agent used their advice, estimated with R standing in for an agent without it, and the
    smallest Δ an experiment of ``seeds`` seeds per arm detects (α = 0.05, power 0.8)."""
    studies.get_study(session, study_id=study_id)
    found = power.study_power(session, study_id=study_id, seeds=seeds)
    return [AdvicePowerOut.model_validate(asdict(p)) for p in found]


@router.get("/{study_id}/candidates")
def list_candidates(study_id: DbId, session: SessionDep, _: ResearcherDep) -> list[CandidateOut]:
    """The candidate states with their images (empty while the study is preparing)."""
    return [
        from_row(
            CandidateOut,
            c,
            image_url=image_url(study_id, c.id),
            thumb_url=image_url(study_id, c.id, "thumb"),
            clip_url=None if c.clip_path is None else clip_url(study_id, c.id),
        )
        for c in studies.list_candidates(session, study_id=study_id)
    ]


@router.get(
    "/{study_id}/candidates/{candidate_id}/image",
    name="candidate_image",
    response_class=FileResponse,
    responses={200: {"content": {MEDIA_TYPE: {}}}},
)
def candidate_image(
    study_id: DbId,
    candidate_id: CandidateId,
    session: SessionDep,
    settings: SettingsDep,
    viewer: ViewerDep,
    size: ImageSize = "full",
    marker: bool = False,
) -> Response:
    """A candidate's rendered image (``size=thumb`` for a small one; ``marker=true`` with
    the marker of an instructed-response gold item drawn on it), for the researcher and
    the study's participants (``<img>`` tags send the role's cookie)."""
    cand = _viewed_candidate(session, viewer, study_id, candidate_id)
    path = image_file(settings.data_dir, cand.image_path if size == "full" else cand.thumb_path)
    if not path.is_file():
        raise NotFoundError(f"the image of candidate {candidate_id} is missing on disk")
    headers = {"Cache-Control": "private, max-age=86400"}
    if marker:
        return Response(with_marker(path.read_bytes()), media_type=MEDIA_TYPE, headers=headers)
    return FileResponse(path, media_type=MEDIA_TYPE, headers=headers)


@router.get(
    "/{study_id}/candidates/{candidate_id}/clip",
    name="candidate_clip",
    response_class=FileResponse,
    responses={200: {"content": {CLIP_MEDIA_TYPE: {}}}},
)
def candidate_clip(
    study_id: DbId,
    candidate_id: CandidateId,
    session: SessionDep,
    settings: SettingsDep,
    viewer: ViewerDep,
) -> Response:
    """A candidate's motion clip (animated WebP; studies with clips, once rendered), to
    whom its image is served; 404 until it is rendered."""
    cand = _viewed_candidate(session, viewer, study_id, candidate_id)
    path = None if cand.clip_path is None else image_file(settings.data_dir, cand.clip_path)
    if path is None or not path.is_file():
        raise NotFoundError(f"candidate {candidate_id} of study {study_id} has no clip")
    headers = {"Cache-Control": "private, max-age=86400"}
    return FileResponse(path, media_type=CLIP_MEDIA_TYPE, headers=headers)


def _viewed_candidate(
    session: Session, viewer: Viewer, study_id: int, candidate_id: int
) -> Candidate:
    """The candidate, for the researcher and the study's own participants only."""
    if not viewer.researcher and (
        viewer.participant is None or viewer.participant.study_id != study_id
    ):
        raise NotFoundError(f"candidate {candidate_id} of study {study_id} not found")
    return studies.get_candidate(session, study_id=study_id, candidate_id=candidate_id)


@router.post("/{study_id}/participants", status_code=201)
def add_participant(
    study_id: DbId,
    request: Request,
    session: SessionDep,
    _: ResearcherDep,
    body: ParticipantCreate | None = None,
) -> ParticipantCreated:
    """Invite one participant; share ``invite_url`` with them."""
    (person,) = participants.add_participants(
        session, study_id=study_id, name=body.name if body else None
    )
    return _created(request, person)


@router.post("/{study_id}/participants/batch", status_code=201)
def add_participants(
    study_id: DbId,
    body: ParticipantBatchCreate,
    request: Request,
    session: SessionDep,
    _: ResearcherDep,
) -> list[ParticipantCreated]:
    """Invite ``count`` participants at once."""
    people = participants.add_participants(
        session, study_id=study_id, count=body.count, name=body.name
    )
    return [_created(request, p) for p in people]


def _created(request: Request, person: Participant) -> ParticipantCreated:
    return from_row(ParticipantCreated, person, invite_url=invite_url(request, person.token))


@router.get("/{study_id}/participants")
def list_participants(
    study_id: DbId, request: Request, session: SessionDep, _: ResearcherDep
) -> list[ParticipantOut]:
    """Participants with their progress, invite links, outcomes and codes."""
    link = recruiting.settings(session, study_link.LINK, study_id)
    return [
        participant_out(request, s.participant, s.progress, link)
        for s in participants.list_participants(session, study_id=study_id)
    ]


def participant_out(
    request: Request,
    person: Participant,
    progress: participants.Progress,
    link: OpenLink | None,
) -> ParticipantOut:
    """A participant as the researcher sees them; ``link``: their study's open link."""
    failed_gate = person.gate_stopped_at is not None
    result = seats.outcome(person, link, utcnow(), failed_gate=failed_gate)
    return from_row(
        ParticipantOut,
        person,
        invite_url=invite_url(request, person.token),
        progress=ProgressOut(done=progress.done, total=progress.total),
        finished=progress.finished,
        outcome=result.name,
        code=result.code,
    )


@router.get(
    "/{study_id}/labels.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def labels_csv(
    study_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    include_excluded: IncludeExcluded = False,
) -> Response:
    """Every label of the study, one row per label (excluded participants' only on request)."""
    text = trees.labels_csv(session, study_id=study_id, include_excluded=include_excluded)
    return attachment(text, "text/csv", f"study-{study_id}-labels.csv")


@router.get("/{study_id}/trees")
def study_trees(
    study_id: DbId,
    session: SessionDep,
    _: ResearcherDep,
    include_excluded: IncludeExcluded = False,
) -> list[dict[str, Any]]:
    """Every finished participant's Human Preference Tree (``acv.tree/1`` documents);
    excluded participants' only on request."""
    found = trees.study_trees(session, study_id=study_id, include_excluded=include_excluded)
    return [{"participant_id": pid, "tree": tree_to_json(doc)} for pid, doc in found]
