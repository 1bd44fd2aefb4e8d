"""One participant's label quality (issues 14 and 28): the flags (position bias, speed,
the consistency check, the gold gate), the one rule the quality table, the live dashboard and
webhook events share (:func:`flags_of`), and the reliability their known-answer checks give.
A study's table of them is :func:`app.labelling.quality.quality`."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from app.labelling.gate import GateStanding, below_gate
from app.labelling.gold_answers import GoldScore
from app.models import Participant
from engine import agreement
from engine.reliability import Checks, competence, gold_interval

#: Position bias is flagged below this p-value of the binomial test.
BIAS_ALPHA = 0.05


def is_fast(median_ms: float | None, threshold_ms: int) -> bool:
    """The speed flag: a median response time under the study's threshold."""
    return median_ms is not None and median_ms < threshold_ms


@lru_cache(maxsize=4096)
def position_biased(left: int, sided: int) -> bool:
    """The position-bias flag: the binomial test of ``left`` of ``sided`` choices against one
    half rejects at :data:`BIAS_ALPHA` (cached: participants share few distinct counts)."""
    p_value = agreement.side_bias(left=left, labels=sided).p_value
    return p_value is not None and p_value < BIAS_ALPHA


def flags_of(
    *,
    left: int,
    sided: int,
    fast: bool,
    consistent: bool | None = None,
    gold: GoldScore = GoldScore(0, 0),
    gate: float | None = None,
) -> list[str]:
    """A participant's quality flags, the one rule for the quality table, the live
    dashboard and webhook events: ``position_bias``, ``fast``, ``inconsistent`` (the
    consistency check differs) and ``below_gate``, when they apply."""
    on = {
        "position_bias": position_biased(left, sided),
        "fast": fast,
        "inconsistent": consistent is False,
        # No gate, no flag: and no interval computed (the finish event's flags have no gate)
        "below_gate": gate is not None and below_gate(gold, gate),
    }
    return [flag for flag, applies in on.items() if applies]


@dataclass(frozen=True)
class ParticipantQuality:
    """One participant's quality; ``gold_gate`` is the study's gate (None: no gate)."""

    participant: Participant
    bias: agreement.SideBias
    median_response_ms: float | None
    fast: bool
    consistency_agrees: bool | None
    gold: GoldScore = GoldScore(0, 0)
    ties: int = 0
    gold_gate: float | None = None

    @property
    def flags(self) -> list[str]:
        """``position_bias``, ``fast``, ``inconsistent`` and ``below_gate`` (:func:`flags_of`)."""
        return flags_of(
            left=self.bias.left,
            sided=self.bias.labels,
            fast=self.fast,
            consistent=self.consistency_agrees,
            gold=self.gold,
            gate=self.gold_gate,
        )

    @property
    def checks(self) -> Checks:
        """The known-answer checks this participant answered: gold items and the
        consistency pair."""
        consistent = self.consistency_agrees
        return Checks(
            gold_right=self.gold.right,
            gold_asked=self.gold.asked,
            consistent=int(bool(consistent)),
            consistency_asked=int(consistent is not None),
        )

    @property
    def gold_interval(self) -> tuple[float, float] | None:
        """Clopper-Pearson 95% interval of gold accuracy (None before any gold item)."""
        return gold_interval(self.checks)

    @property
    def standing(self) -> GateStanding:
        """What the gold gate reads of this participant."""
        return GateStanding(self.participant, self.gold, self.gold_gate)

    @property
    def below_gate(self) -> bool:
        """Whether the study's gate flags this participant (:func:`below_gate`)."""
        return self.standing.below_gate

    @property
    def gate_reason(self) -> str:
        """Why the gate flags this participant, in words."""
        return self.standing.gate_reason

    @property
    def reliability(self) -> float:
        """MACE competence from :attr:`checks` (:func:`engine.reliability.competence`): 0.25
        before any check, never from agreement with others (docs/method.md §2.13)."""
        return competence(self.checks)
