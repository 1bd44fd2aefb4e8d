"""The gold gate under the null (issue 28 §1): a participant whose true gold accuracy is the
gate itself is flagged at most 2.5% of the time, whatever the number of items, because the
gate reads the upper bound of the exact 95% Clopper-Pearson interval. Computed exactly over
the binomial distribution of right answers, not by simulation."""

from __future__ import annotations

import pytest
from scipy.stats import binom

from app.labelling.gate import below_gate
from app.labelling.gold_answers import GoldScore


def _flag_rate(accuracy: float, asked: int, gate: float) -> float:
    """P(flagged) for a participant right with probability ``accuracy`` on each item."""
    return sum(
        binom.pmf(right, asked, accuracy)
        for right in range(asked + 1)
        if below_gate(GoldScore(right, asked), gate)
    )


@pytest.mark.parametrize("gate", [0.5, 0.8, 0.9, 0.95])
@pytest.mark.parametrize("asked", [1, 2, 3, 5, 10, 20])
def test_a_careful_participant_at_the_gate_is_rarely_flagged(gate: float, asked: int) -> None:
    assert _flag_rate(gate, asked, gate) <= 0.025 + 1e-12
    assert _flag_rate(min(1.0, gate + 0.05), asked, gate) <= 0.025 + 1e-12  # better: rarer


@pytest.mark.parametrize("asked", [5, 10, 20])
def test_a_clicker_is_flagged_once_there_are_items_enough(asked: int) -> None:
    """A random clicker (accuracy 0.5) against a gate of 0.9: flagged more often with more
    items (the power side of the same rule)."""
    rates = [_flag_rate(0.5, n, 0.9) for n in (asked, 2 * asked)]
    assert 0 < rates[0] < rates[1]
    assert _flag_rate(0.5, 20, 0.9) > 0.9
