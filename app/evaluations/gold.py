"""An evaluation's gold pairs and its gate (issue 41): the studies' instructed gold items
and gold gate, applied to evaluators.

An evaluation with ``gold_pairs = g`` gives each evaluator ``g`` instructed pairs ("choose
the picture with the marker"): two of the evaluation's stills, the marker drawn on the
answer's (:func:`engine.render.image.with_marker`, as a study's instructed items), at
positions among the real pairs drawn from the evaluation's seed and the evaluator, as a
study places its gold items (:func:`app.labelling.gold_placement.positions`). A gold pair is
an ``evaluation_pairs`` row like any other (an opaque key, slots and windows, seeded sides)
whose ``gold_answer`` is the marked slot; it never enters the result. After each gold answer
the evaluator's gold score is read against the evaluation's gate as a study's
(:func:`app.labelling.gate.below_gate`); an evaluator clearly below it is excluded.
"""

from __future__ import annotations

import secrets

import numpy as np
from sqlalchemy import case, func, select, update
from sqlalchemy.orm import Session

from app.labelling.gate import GateStanding, below_gate
from app.labelling.gold_answers import GoldScore
from app.labelling.gold_placement import INSTRUCTED_PROMPT, positions
from app.models import Evaluation, EvaluationPair, Evaluator

__all__ = [
    "INSTRUCTED_PROMPT",
    "gate_after_answer",
    "gate_excluded",
    "gold_pairs",
    "gold_places",
    "score",
]

#: The entropy word of gold pairs' generator stream (issue 41).
_STREAM = 41


def gold_places(evaluation: Evaluation, person: Evaluator) -> list[int]:
    """Before which real pair (its index, from 0) each of the evaluator's gold pairs goes:
    after a first real pair and before the last, as a study's gold items
    (:func:`app.labelling.gold_placement.positions`)."""
    if evaluation.gold_pairs == 0:
        return []
    return positions(
        n_candidates=evaluation.pairs_per_evaluator + 1,
        count=evaluation.gold_pairs,
        seed=evaluation.seed,
        participant_id=person.id,
    )


def gold_pairs(
    evaluation: Evaluation, person: Evaluator, windows: list[int]
) -> list[EvaluationPair]:
    """The evaluator's gold pairs, without positions yet: two different slots (seeded), a
    seeded window each, seeded sides, and the marked slot (their ``gold_answer``)."""
    rng = np.random.default_rng([evaluation.seed, person.id, _STREAM])
    found = []
    for _ in range(evaluation.gold_pairs):
        a, b = (int(s) for s in rng.choice(len(windows), size=2, replace=False))
        found.append(
            EvaluationPair(
                evaluator_id=person.id,
                key=secrets.token_urlsafe(16),
                a=a,
                b=b,
                window_a=int(rng.integers(windows[a])),
                window_b=int(rng.integers(windows[b])),
                a_left=bool(rng.integers(2)),
                tie=False,
                gold_answer=a if rng.integers(2) else b,
            )
        )
    return found


def score(session: Session, *, evaluator_id: int) -> GoldScore:
    """The evaluator's gold answers so far: how many, and how many right (a tie is wrong)."""
    right, asked = session.execute(
        select(
            func.sum(case((EvaluationPair.winner == EvaluationPair.gold_answer, 1), else_=0)),
            func.count(),
        ).where(
            EvaluationPair.evaluator_id == evaluator_id,
            EvaluationPair.gold_answer.is_not(None),
            EvaluationPair.answered_at.is_not(None),
        )
    ).one()
    return GoldScore(int(right or 0), int(asked))


def gate_after_answer(session: Session, evaluator: Evaluator, evaluation: Evaluation) -> bool:
    """After a gold answer, in its write transaction: exclude the evaluator when their gold
    score is clearly below the evaluation's gate. Returns whether they are excluded now."""
    standing = score(session, evaluator_id=evaluator.id)
    if not below_gate(standing, evaluation.gold_gate):
        return False
    # the study's sentence for it: it reads the score and the gate, not who they are
    reason = GateStanding(evaluator, standing, evaluation.gold_gate).gate_reason  # type: ignore[arg-type]
    session.execute(
        update(Evaluator)
        .where(Evaluator.id == evaluator.id, Evaluator.excluded.is_(False))
        .values(excluded=True, exclusion_reason=reason[:200])
    )
    return True


def gate_excluded(session: Session, *, evaluation_id: int) -> int:
    """How many of the evaluation's evaluators the gold gate left out."""
    return int(
        session.scalar(
            select(func.count())
            .select_from(Evaluator)
            .where(
                Evaluator.evaluation_id == evaluation_id,
                Evaluator.excluded.is_(True),
                Evaluator.exclusion_reason.like("gold gate%"),
            )
        )
        or 0
    )
