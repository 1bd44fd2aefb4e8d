"""``/api/studies/{id}/crowd``, ``/quality``, ``/agreement`` and ``/export/labels.*``: a
study's open link and options, label quality, agreement across participants, and the labels
for reuse (issue 14). Researcher only."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fastapi import APIRouter, Response

from app.core.errors import NotFoundError
from app.http.deps import DbId, ResearcherDep, SessionDep
from app.http.files import attachment
from app.labelling import consensus, label_export, quality, study_link
from app.recruiting.api import LinkApi, open_link_api_router
from app.studies import crowd
from app.studies.crowd_schemas import (
    AgreementOut,
    CrowdIn,
    CrowdOut,
    PairAgreementOut,
    ParticipantQualityOut,
    QualityOut,
    SideBiasOut,
    TeacherAgreementOut,
)
from app.studies.schemas import IncludeExcluded

router = APIRouter(prefix="/studies", tags=["crowd"])


#: ``/studies/{study_id}/crowd``: the study's open link ``/s/<slug>`` with its label-quality
#: options.
link_router = open_link_api_router(
    LinkApi(
        kind=study_link.LINK,
        collections="studies",
        tag="crowd",
        name="crowd",
        body=CrowdIn,
        out=CrowdOut,
        options=crowd.CrowdOptions,
        configure=lambda session, study_id, options: quality.configure_crowd(
            session, study_id=study_id, options=options
        ),
    )
)


def _bias(b: quality.agreement.SideBias) -> SideBiasOut:
    return SideBiasOut(labels=b.labels, left=b.left, left_share=b.left_share, p_value=b.p_value)


@router.get("/{study_id}/quality")
def get_quality(study_id: DbId, session: SessionDep, _: ResearcherDep) -> QualityOut:
    """Position bias (share of left choices, binomial test) per participant and study,
    median response times with the speed flag, consistency-check agreement, gold accuracy
    with its interval and the gate, reliability, ties and exclusions."""
    q = quality.quality(session, study_id=study_id)
    return QualityOut(
        study_id=study_id,
        speed_threshold_ms=q.speed_threshold_ms,
        gold_gate=q.gold_gate,
        position_bias=_bias(q.bias),
        participants=[
            ParticipantQualityOut(
                participant_id=p.participant.id,
                name=p.participant.name,
                external_id=p.participant.external_id,
                position_bias=_bias(p.bias),
                median_response_ms=p.median_response_ms,
                fast=p.fast,
                consistency_agrees=p.consistency_agrees,
                reliability=p.reliability,
                reliability_checks=p.checks.asked,
                gold_right=p.gold.right,
                gold_asked=p.gold.asked,
                gold_interval=p.gold_interval,
                ties=p.ties,
                excluded=p.participant.excluded,
                exclusion_reason=p.participant.exclusion_reason,
                flags=p.flags,
            )
            for p in q.participants
        ],
    )


@router.get("/{study_id}/agreement")
def get_agreement(study_id: DbId, session: SessionDep, _: ResearcherDep) -> AgreementOut:
    """Pairwise agreement on shared pairs and its mean, Krippendorff's alpha (nominal), and
    each participant's agreement with the simulated teachers."""
    a = consensus.study_agreement(session, study_id=study_id)
    return AgreementOut(
        study_id=study_id,
        participants=a.participants,
        pairs=[PairAgreementOut(**vars(p)) for p in a.pairs],
        mean_agreement=a.mean,
        krippendorff_alpha=a.alpha,
        shared_pairs=a.shared_pairs,
        teachers=[TeacherAgreementOut(**vars(t)) for t in a.teachers],
    )


_EXPORTS: dict[str, tuple[str, Callable[[list[dict[str, Any]]], bytes | str]]] = {
    "jsonl": ("application/x-ndjson", label_export.to_jsonl),
    "csv": ("text/csv", label_export.to_csv),
    "parquet": ("application/vnd.apache.parquet", label_export.to_parquet),
}


@router.get(
    "/{study_id}/export/labels.{fmt}",
    response_class=Response,
    responses={200: {"content": {t: {} for t, _ in _EXPORTS.values()}}},
)
def export_labels(
    study_id: DbId,
    fmt: str,
    session: SessionDep,
    _: ResearcherDep,
    include_excluded: IncludeExcluded = False,
) -> Response:
    """One row per label (``jsonl``, ``csv`` or ``parquet``), with external ids, sides,
    times, ties, and the participant's quality flags, reliability and exclusion."""
    if fmt not in _EXPORTS:
        raise NotFoundError(f"unknown export format {fmt!r}: expected jsonl, csv or parquet")
    media_type, write = _EXPORTS[fmt]
    body = write(
        label_export.records(session, study_id=study_id, include_excluded=include_excluded)
    )
    return attachment(body, media_type, f"study-{study_id}-labels.{fmt}")
