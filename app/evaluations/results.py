"""An evaluation's answer (issue 41 §2): the kept evaluators' answers pooled per run pair,
tested by :func:`engine.evaluation.stats.evaluate`, and its export.

Kept: evaluators not withdrawn, not excluded (the gold gate excludes, :mod:`app.evaluations.gold`),
and within their time (the members' rule, :func:`app.recruiting.seats.kept_in_data`); an
unanswered pair and a gold pair count nowhere, and the exports leave gold pairs out. The interval's
bootstrap is seeded by the evaluation, so the same answers always read the same.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.evaluations import service
from app.models import Evaluation, EvaluationPair, Evaluator, as_utc, utcnow
from app.recruiting import seats
from engine.evaluation.outcome import EvaluationResult, evaluate
from engine.evaluation.power import MAX_EVALUATORS
from engine.evaluation.stats import Answers

#: How the tree verdict and an evaluation can differ, said beside the answer wherever both
#: are shown.
TREE_VS_ASKED = (
    '"Followed your tree" (the verdict on the experiment page) asks whether the agents '
    'learned the reward made from the tree\'s postures; "does what you asked" (this '
    "evaluation) asks people who watch the agents, so an agent can follow the tree without "
    "doing what was meant, and the two answers can differ."
)
#: Columns of an evaluation's answers export, one row per answered pair. Slots, never runs:
#: the export is the researcher's, but a slot's run is listed beside it (``runs``).
EXPORT_COLUMNS = (
    "evaluator_id",
    "position",
    "slot_a",
    "slot_b",
    "run_a",
    "run_b",
    "a_advised",
    "b_advised",
    "a_left",
    "winner_slot",
    "tie",
    "chose_left",
    "response_ms",
    "stimulus",
    "reminder",
    "answered_at",
)


def kept_pairs(session: Session, *, evaluation_id: int) -> list[EvaluationPair]:
    """The answered pairs of the evaluation's kept evaluators, by evaluator and position."""
    kept = seats.kept_in_data(include_excluded=False, now=utcnow(), excluded=Evaluator.excluded)
    query = (
        select(EvaluationPair)
        .join(Evaluator, Evaluator.id == EvaluationPair.evaluator_id)
        .where(
            Evaluator.evaluation_id == evaluation_id,
            EvaluationPair.answered_at.is_not(None),
            EvaluationPair.gold_answer.is_(None),  # gold pairs never enter the result
            *kept,
        )
        .order_by(EvaluationPair.evaluator_id, EvaluationPair.position)
    )
    return list(session.scalars(query))


def answers_of(pairs: list[EvaluationPair]) -> Answers:
    """The engine's view of answered pairs: a tie counts 1/2 to each side."""
    return Answers(
        a=np.array([p.a for p in pairs], dtype=np.int64),
        b=np.array([p.b for p in pairs], dtype=np.int64),
        winner_is_a=np.array([_score(p) for p in pairs], dtype=np.float64),
        chose_left=np.array([bool(p.chose_left) for p in pairs], dtype=bool),
        evaluator=np.array([p.evaluator_id for p in pairs], dtype=np.int64),
    )


def _score(pair: EvaluationPair) -> float:
    return 0.5 if pair.tie else float(pair.winner == pair.a)


@dataclass(frozen=True)
class EvaluationAnswer:
    """The evaluation's result now, with what it rests on. ``final``: the design's evaluators
    (:func:`planned_evaluators`) have all finished. Only a final answer gets its outcome in
    words; each earlier look is interim, since looking after every answer must not give many
    chances to say "more"."""

    result: EvaluationResult
    advised: tuple[bool, ...]
    run_ids: tuple[int, ...]
    finished: int
    planned: int

    @property
    def final(self) -> bool:
        """As many kept evaluators have finished as the design planned."""
        return self.finished >= self.planned

    def to_json(self) -> dict[str, Any]:
        return {
            **self.result.to_json(),
            "sentence": self.result.sentence if self.final else self.interim_sentence(),
            "final": self.final,
            "finished_evaluators": self.finished,
            "planned_evaluators": self.planned,
            "slots": [
                {"slot": s, "run_id": r, "advised": a}
                for s, (r, a) in enumerate(zip(self.run_ids, self.advised, strict=True))
            ],
        }

    def interim_sentence(self) -> str:
        """What an interim look says in place of the outcome."""
        return (
            f"Interim: no answer yet. It is given once {self.planned} evaluators have "
            f"finished ({self.finished} so far); this look shows the win rates and the "
            "interval only."
        )


def planned_evaluators(evaluation: Evaluation) -> int:
    """The evaluators the design planned: its size for the target at 80% power, or the most
    it is sized to when no count reaches that power (:data:`MAX_EVALUATORS`)."""
    return evaluation.needed_evaluators or MAX_EVALUATORS


def finished_evaluators(session: Session, *, evaluation_id: int) -> int:
    """Kept evaluators who have answered all their pairs."""
    kept = seats.kept_in_data(include_excluded=False, now=utcnow(), excluded=Evaluator.excluded)
    query = select(func.count(Evaluator.id)).where(
        Evaluator.evaluation_id == evaluation_id, Evaluator.finished_at.is_not(None), *kept
    )
    return int(session.scalar(query) or 0)


def result(session: Session, *, evaluation_id: int) -> EvaluationAnswer:
    """The evaluation's answer from its kept evaluators' answers so far."""
    evaluation = service.get_evaluation(session, evaluation_id=evaluation_id)
    slots = service.slots(session, evaluation_id=evaluation_id)
    advised = np.array([s.advised for s in slots], dtype=bool)
    answers = answers_of(kept_pairs(session, evaluation_id=evaluation_id))
    rng = np.random.default_rng([evaluation.seed, 2])
    found = evaluate(answers, advised, rng, evaluation.evaluator_kind)  # type: ignore[arg-type]
    return EvaluationAnswer(
        found,
        tuple(advised.tolist()),
        tuple(s.run_id for s in slots),
        finished=finished_evaluators(session, evaluation_id=evaluation_id),
        planned=planned_evaluators(evaluation),
    )


def export_rows(session: Session, *, evaluation_id: int) -> list[dict[str, Any]]:
    """One row per kept answered pair, in :data:`EXPORT_COLUMNS`."""
    slots = service.slots(session, evaluation_id=evaluation_id)
    rows = []
    for pair in kept_pairs(session, evaluation_id=evaluation_id):
        a, b = slots[pair.a], slots[pair.b]
        rows.append(
            {
                "evaluator_id": pair.evaluator_id,
                "position": pair.position,
                "slot_a": pair.a,
                "slot_b": pair.b,
                "run_a": a.run_id,
                "run_b": b.run_id,
                "a_advised": a.advised,
                "b_advised": b.advised,
                "a_left": pair.a_left,
                "winner_slot": pair.winner,
                "tie": pair.tie,
                "chose_left": pair.chose_left,
                "response_ms": pair.response_ms,
                "stimulus": pair.stimulus,
                "reminder": pair.reminder,
                "answered_at": pair.answered_at,
            }
        )
    return rows


def _json_value(value: Any) -> Any:
    """A cell as JSON holds it: a time as ISO 8601 in UTC, anything else as it is."""
    return as_utc(value).isoformat() if isinstance(value, datetime) else value


def to_jsonl(rows: list[dict[str, Any]]) -> str:
    """:func:`export_rows` as JSON Lines, one object a row in :data:`EXPORT_COLUMNS`'s order
    (``answered_at`` as ISO 8601 in UTC)."""
    return "".join(
        json.dumps({c: _json_value(r.get(c)) for c in EXPORT_COLUMNS}) + "\n" for r in rows
    )


def to_parquet(rows: list[dict[str, Any]]) -> bytes:
    """:func:`export_rows` as a Parquet file that ``datasets.load_dataset("parquet", ...)``
    reads: flat typed columns in :data:`EXPORT_COLUMNS`'s order, the same schema when empty."""
    import pyarrow as pa  # imported here: only this export needs it
    import pyarrow.parquet as pq

    types = {"stimulus": pa.string(), "answered_at": pa.timestamp("us", tz="UTC")}
    for name in ("a_advised", "b_advised", "a_left", "tie", "chose_left", "reminder"):
        types[name] = pa.bool_()
    schema = pa.schema([(c, types.get(c, pa.int64())) for c in EXPORT_COLUMNS])
    flat = [
        {**r, "answered_at": None if r["answered_at"] is None else as_utc(r["answered_at"])}
        for r in rows
    ]
    buffer = io.BytesIO()
    pq.write_table(pa.Table.from_pylist(flat, schema=schema), buffer)
    return buffer.getvalue()


def notes_of_experiments(session: Session, experiment_ids: list[int]) -> dict[str, Any]:
    """The agent evaluations of ``experiment_ids``, for pages that show them beside the tree
    verdict: ``evaluations`` (each its id, experiment and answer's sentence, newest first per
    experiment) and ``tree_vs_asked`` (:data:`TREE_VS_ASKED`)."""
    found = []
    for experiment_id in experiment_ids:
        for evaluation in service.list_evaluations(session, experiment_id=experiment_id):
            sentence = str(result(session, evaluation_id=evaluation.id).to_json()["sentence"])
            found.append(
                {"id": evaluation.id, "experiment_id": experiment_id, "sentence": sentence}
            )
    return {"evaluations": found, "tree_vs_asked": TREE_VS_ASKED}
