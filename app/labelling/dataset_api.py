"""A study's shared dataset (issue 29 §4): the researcher downloads it as a zip, and a
participant says whether their labels may be in it (``share-consent``)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response

from app.core.auth import dataset_salt
from app.http.deps import DbId, ResearcherDep, SessionDep, SettingsDep
from app.http.files import attachment
from app.http.member_auth import ParticipantDep
from app.labelling import dataset, participants
from app.labelling.dataset_card import DEFAULT_LICENSE
from app.labelling.schemas import ShareConsentIn, ShareConsentOut

router = APIRouter()


@router.get(
    "/studies/{study_id}/export/dataset.zip",
    tags=["crowd"],
    response_class=Response,
    responses={
        200: {"content": {"application/zip": {}}},
        409: {"description": "No participant who agreed to share has labelled a pair."},
    },
)
def export_dataset(
    study_id: DbId,
    session: SessionDep,
    settings: SettingsDep,
    _: ResearcherDep,
    license: Annotated[
        str, Query(max_length=64, description="The dataset's licence, as the Hub names it.")
    ] = DEFAULT_LICENSE,
) -> Response:
    """A folder that ``datasets.load_dataset("parquet", data_dir=...)`` loads, zipped: labels,
    candidates with their states and pictures, pseudonymous participants and their trees,
    and a dataset card; only participants who agreed to share, and not excluded."""
    made = dataset.build(
        session,
        study_id=study_id,
        salt=dataset_salt(settings),
        data_dir=settings.data_dir,
        license=license,
    )
    name = f"study-{study_id}-dataset"
    return attachment(dataset.zipped(made, folder=name), "application/zip", f"{name}.zip")


@router.put(
    "/participants/me/share-consent",
    tags=["participants"],
    responses={410: {"description": "They withdrew: their labels are never shared."}},
)
def share_consent(
    body: ShareConsentIn, person: ParticipantDep, session: SessionDep
) -> ShareConsentOut:
    """Agree, or no longer agree, that your labels may be shared in a public dataset under a
    pseudonym; off unless you agree. An export made afterwards follows your latest choice."""
    row = participants.set_share_consent(session, participant_id=person.id, share=body.share)
    return ShareConsentOut(share=row.share_consent)
