"""Exports: a finished participant's Human Preference Tree (``acv.tree/1``) and label CSVs."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core import csv_export
from app.core.errors import ConflictError
from app.labelling.participants import get_participant
from app.labelling.service import results_of
from app.models import Label, Match, Participant, as_utc, utcnow
from app.recruiting.seats import kept_in_data
from app.studies.service import engine_candidates_of, first_round, get_study
from engine.treefile import TreeDocument, make_document

LABEL_COLUMNS = (
    "study_id",
    "participant_id",
    "match_id",
    "round",
    "slot",
    "a",
    "b",
    "winner",
    "labelled_at",
    "response_ms",
    "tie",
    "stimulus",
)


def judge_name(participant_id: int) -> str:
    """How a participant is named as the judge of their tree."""
    return f"participant:{participant_id}"


def participant_tree(session: Session, *, participant_id: int) -> TreeDocument:
    """The Human Preference Tree of a participant who finished the bracket.

    Raises:
        NotFoundError: no such participant.
        ConflictError: the bracket is not finished yet.
    """
    participant = get_participant(session, participant_id=participant_id)
    study = get_study(session, study_id=participant.study_id)
    results = results_of(session, participant_id=participant_id)
    if len(results) < study.n_candidates - 1:
        raise ConflictError(
            f"participant {participant_id} has not finished the bracket "
            f"({len(results)} of {study.n_candidates - 1} matches labelled)"
        )
    return make_document(
        env_id=study.env_id,
        seed=study.seed,
        p=study.p,
        judge=judge_name(participant_id),
        candidates=engine_candidates_of(session, study_id=study.id),
        first_round=first_round(session, study_id=study.id),
        results=results,
        ties=ties_of(session, participant_id=participant_id),
    )


def ties_of(session: Session, *, participant_id: int) -> frozenset[tuple[int, int]]:
    """``(round, slot)`` of the participant's matches labelled "can't tell" (``Label.tie``);
    their ``winner`` is the seeded coin's (docs/method.md §2.14)."""
    rows = session.execute(
        select(Match.round, Match.slot)
        .join(Label, Label.match_id == Match.id)
        .where(Match.participant_id == participant_id, Label.tie.is_(True))
    )
    return frozenset((r, s) for r, s in rows)


def study_trees(
    session: Session, *, study_id: int, include_excluded: bool = False
) -> list[tuple[int, TreeDocument]]:
    """``(participant id, tree)`` of every participant of the study who has finished;
    excluded participants' only with ``include_excluded``, as in every export."""
    get_study(session, study_id=study_id)
    kept = kept_in_data(include_excluded=include_excluded, now=utcnow())
    finished = session.scalars(
        select(Participant.id)
        .where(Participant.study_id == study_id, Participant.finished_at.is_not(None), *kept)
        .order_by(Participant.id)
    )
    return [(pid, participant_tree(session, participant_id=pid)) for pid in finished]


def labels_csv(session: Session, *, study_id: int, include_excluded: bool = False) -> str:
    """Every label of the study as CSV (header :data:`LABEL_COLUMNS`), in label order;
    excluded participants' labels only with ``include_excluded`` (they are never deleted)."""
    get_study(session, study_id=study_id)
    kept = kept_in_data(include_excluded=include_excluded, now=utcnow())
    rows = session.execute(
        select(
            Match.participant_id,
            Label.match_id,
            Match.round,
            Match.slot,
            Match.a,
            Match.b,
            Label.winner,
            Label.created_at,
            Label.response_ms,
            Label.tie,
            Label.stimulus,
        )
        .join(Match, Match.id == Label.match_id)
        .join(Participant, Participant.id == Match.participant_id)
        .where(Participant.study_id == study_id, *kept)
        .order_by(Label.id)
    )
    return csv_export.csv_text(
        LABEL_COLUMNS,
        (
            (study_id, pid, mid, rnd, slot, a, b, w, as_utc(at).isoformat(), ms, bool(tie), stim)
            for pid, mid, rnd, slot, a, b, w, at, ms, tie, stim in rows
        ),
    )
