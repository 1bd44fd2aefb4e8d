"""How much to trust each participant's labels, from the answers whose right answer is known
(issue 28 §2; docs/method.md §2.13).

Two kinds of check have one: **gold items**, pairs with an objective winner ("choose the
picture with the marker"), and **consistency pairs**, a match asked again with its sides
swapped, whose right answer is the posture chosen the first time. Agreement with other
participants is deliberately left out: a minority with another taste disagrees with the
majority by design, and a model with one truth per item would count that taste as noise.

The model is MACE's for two options (Hovy et al., 2013, "Learning Whom to Trust with MACE"):
a participant answers with care with probability θ, their *competence*, and is then right;
otherwise they pick a side at random, right half the time. So P(right) = (1 + θ) / 2. A
careful participant's own taste noise counts against θ a little (a swapped pair repeated
with noise ε agrees with probability 1 - 2ε(1 - ε)); an always-left clicker contradicts every
swapped pair, and gets θ = 0.

With the truth of every check known, MACE's EM has nothing to infer: θ's posterior is in
closed form (a uniform prior on P(right) gives Beta(1 + k, 1 + n - k)), hence no library
call. The weight of a participant is E[max(0, 2 P(right) - 1)], the posterior mean of θ
truncated at 0: few checks give a cautious weight, many give θ.
"""

from __future__ import annotations

from dataclasses import dataclass

import scipy
from scipy.special import betaincc

from engine.errors import InputError


@dataclass(frozen=True)
class Checks:
    """One participant's known-answer checks.

    Attributes:
        gold_right: gold items answered right.
        gold_asked: gold items answered.
        consistent: consistency pairs answered the same way both times.
        consistency_asked: consistency pairs answered (both times).
    """

    gold_right: int = 0
    gold_asked: int = 0
    consistent: int = 0
    consistency_asked: int = 0

    def __post_init__(self) -> None:
        for right, asked in (
            (self.gold_right, self.gold_asked),
            (self.consistent, self.consistency_asked),
        ):
            if not 0 <= right <= asked:
                raise InputError(f"checks must have 0 <= right <= asked, got {right} of {asked}")

    @property
    def right(self) -> int:
        return self.gold_right + self.consistent

    @property
    def asked(self) -> int:
        return self.gold_asked + self.consistency_asked


def competence(checks: Checks) -> float:
    """E[θ+]: the posterior mean of MACE's competence, truncated at 0, in [0, 1].

    With no check answered it is the prior's, 0.25: nothing is known either way.
    """
    a, b = 1.0 + checks.right, 1.0 + checks.asked - checks.right
    # E[(2X - 1) 1{X > 1/2}] for X ~ Beta(a, b): X Beta(a, b) = a/(a+b) Beta(a+1, b). Beta's
    # survival function is the regularised incomplete beta's complement, from scipy.special:
    # scipy.stats costs seconds to import, and every labelling process reaches this line.
    above = float(betaincc(a, b, 0.5))
    x_above = a / (a + b) * float(betaincc(a + 1, b, 0.5))
    return max(0.0, 2.0 * x_above - above)


def gold_interval(checks: Checks, level: float = 0.95) -> tuple[float, float] | None:
    """The Clopper-Pearson interval of gold accuracy; None before any gold item."""
    if checks.gold_asked == 0:
        return None
    ci = scipy.stats.binomtest(checks.gold_right, checks.gold_asked).proportion_ci(
        level, method="exact"
    )
    return float(ci.low), float(ci.high)
