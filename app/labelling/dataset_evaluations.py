"""The shared dataset's ``evaluations`` config (issue 41: an evaluation "is exported with the
labels and in the HF dataset, with the stimulus kind"): one row per answered pair of the
agent evaluations of a study's runs, from evaluators who agreed to share their answers.

An evaluation belongs to the dataset of every study one of its runs trained on. Evaluators
are named as participants are (:class:`app.labelling.pseudonyms.Pseudonyms`, kind
``evaluator``), and so are runs (kind ``run``): a run keeps one key across evaluations of
the same study, so its answers can be pooled, but its id, seed and checkpoint are not in
the dataset. Only evaluators who agreed (``share_consent``) and are kept in the data (not
withdrawn, excluded or out of time: :func:`app.recruiting.seats.kept_in_data`); the day of
each answer, never its time of day.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.models import (
    Evaluation,
    EvaluationPair,
    EvaluationRun,
    Evaluator,
    Run,
    as_utc,
    utcnow,
)
from app.recruiting.seats import kept_in_data

if TYPE_CHECKING:
    from app.labelling.pseudonyms import Pseudonyms

Rows = list[dict[str, Any]]


def evaluation_ids(session: Session, *, study_id: int) -> list[int]:
    """The evaluations with a run of the study, oldest first."""
    query = (
        select(EvaluationRun.evaluation_id)
        .join(Run, Run.id == EvaluationRun.run_id)
        .where(Run.study_id == study_id)
        .distinct()
    )
    return sorted(session.scalars(query))


def evaluation_rows(session: Session, *, study_id: int, hashes: Pseudonyms) -> Rows:
    """One row per answered pair of the study's evaluations' sharing, kept evaluators, in
    the columns of :data:`app.labelling.dataset_tables.EVALUATIONS`, by evaluation, then
    evaluator pseudonym, then position."""
    ids = evaluation_ids(session, study_id=study_id)
    if not ids:
        return []
    kept = kept_in_data(include_excluded=False, now=utcnow(), excluded=Evaluator.excluded)
    found = session.execute(
        select(EvaluationPair, Evaluator.evaluation_id)
        .join(Evaluator, Evaluator.id == EvaluationPair.evaluator_id)
        .where(
            Evaluator.evaluation_id.in_(ids),
            Evaluator.share_consent.is_(True),
            EvaluationPair.answered_at.is_not(None),
            EvaluationPair.gold_answer.is_(None),  # gold pairs are checks, not judgements
            *kept,
        )
    ).all()
    evaluations = {
        e.id: e for e in session.scalars(select(Evaluation).where(Evaluation.id.in_(ids)))
    }
    slots = {
        (s.evaluation_id, s.slot): s
        for s in session.scalars(select(EvaluationRun).where(EvaluationRun.evaluation_id.in_(ids)))
    }
    rows = [_row(pair, evaluations[eid], slots, hashes) for pair, eid in found]
    return sorted(rows, key=lambda r: (r["evaluation"], r["evaluator"], r["position"]))


def _row(
    pair: EvaluationPair,
    evaluation: Evaluation,
    slots: dict[tuple[int, int], EvaluationRun],
    hashes: Pseudonyms,
) -> dict[str, Any]:
    left, right = (pair.a, pair.b) if pair.a_left else (pair.b, pair.a)
    sides = {}
    for side, slot in (("left", left), ("right", right)):
        run = slots[(evaluation.id, slot)]
        sides[f"{side}_run"] = hashes.of("run", run.run_id)
        sides[f"{side}_arm"] = "advised" if run.advised else "baseline"
    winner = (
        None if pair.tie or pair.winner is None else ("left" if pair.winner == left else "right")
    )
    assert pair.answered_at is not None  # only answered pairs are read
    return {
        "evaluation": evaluation.id,
        "evaluator_kind": evaluation.evaluator_kind,
        "question": evaluation.question,
        "evaluator": hashes.of("evaluator", pair.evaluator_id),
        "position": pair.position,
        **sides,
        "winner": winner,
        "tie": pair.tie,
        "response_ms": pair.response_ms,
        "stimulus": pair.stimulus,
        "reminder": bool(pair.reminder),
        "answered_on": as_utc(pair.answered_at).date().isoformat(),
    }
