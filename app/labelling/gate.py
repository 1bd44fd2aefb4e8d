"""The gold gate's reading of one participant (issue 28 §2): their gold answers against the
study's gate. :mod:`app.labelling.quality` applies it to a whole study; after a gold answer,
the participant's standing is read in the answer's own transaction (their earlier answers
counted, plus this one: :func:`app.labelling.gold_answers.answer`) and the gate does more only when
it flags them (:func:`app.labelling.quality.gate_after_answer`; issue 45 §7)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from app.labelling.gold_answers import GoldScore
from app.models import Participant
from engine.reliability import Checks, gold_interval


@lru_cache(maxsize=4096)
def below_gate(gold: GoldScore, gate: float | None) -> bool:
    """The gate's flag: even the upper bound of gold accuracy's 95% Clopper-Pearson interval
    is below the gate, so clearly careless, not merely unlucky on a few items."""
    interval = gold_interval(Checks(gold_right=gold.right, gold_asked=gold.asked))
    return gate is not None and interval is not None and interval[1] < gate


@dataclass(frozen=True)
class GateStanding:
    """What the gold gate reads of one participant: their gold answers, and the gate."""

    participant: Participant
    gold: GoldScore
    gate: float | None

    @property
    def below_gate(self) -> bool:
        """Whether the gate flags this participant (:func:`below_gate`)."""
        return below_gate(self.gold, self.gate)

    @property
    def gate_reason(self) -> str:
        """Why the gate flags this participant, in words."""
        checks = Checks(gold_right=self.gold.right, gold_asked=self.gold.asked)
        low, high = gold_interval(checks) or (0.0, 1.0)
        return (
            f"gold gate: {self.gold.right} of {self.gold.asked} gold items right "
            f"(95% interval {low:.2f} to {high:.2f}, below {self.gate:g})"
        )
