"""Statistics of a survey's answers: a proportion with its Clopper-Pearson 95% interval and
an exact two-sided binomial test against chance (:func:`scipy.stats.binomtest`), and the
paper's own figures computed the same way.

Nothing here touches the database: :mod:`app.surveys.results` gathers the answers.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import scipy

#: Confidence level of every interval.
CONFIDENCE_LEVEL = 0.95
#: The paper's user study (Section "Experiments"): 20 participants; 100% said the trees
#: express different preferences (Q1), 85% read "bent posture" off the second tree (Q2).
PAPER_FIGURES = (
    ("q1", "The trees express different preferences", 20, 20),
    ("q2", "Tree 2 prefers a bent posture", 17, 20),
)


@dataclass(frozen=True)
class Proportion:
    """``k`` of ``n`` answers as expected, with interval and test against ``chance``."""

    k: int
    n: int
    proportion: float
    ci_low: float
    ci_high: float
    chance: float
    p_value: float
    alternative: str = "two-sided"
    method: str = "Clopper-Pearson (exact) 95% CI; exact binomial test"

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def proportion(k: int, n: int, *, chance: float) -> Proportion | None:
    """``k`` successes in ``n`` trials: the exact CI and the exact binomial test.

    Returns ``None`` when ``n == 0`` (no answer: nothing to estimate).
    """
    return None if n == 0 else _exact(k, n, chance=chance)


def _exact(k: int, n: int, *, chance: float) -> Proportion:
    test = scipy.stats.binomtest(k, n, p=chance, alternative="two-sided")
    ci = test.proportion_ci(confidence_level=CONFIDENCE_LEVEL, method="exact")
    return Proportion(
        k=k,
        n=n,
        proportion=k / n,
        ci_low=float(ci.low),
        ci_high=float(ci.high),
        chance=chance,
        p_value=float(test.pvalue),
    )


@dataclass(frozen=True)
class VersusNeutral:
    """Likert answers against the scale's stated neutral value (its midpoint): an exact
    two-sided sign test, answers at the neutral value left out (none left: no p-value).

    A Likert answer is not right or wrong, so it is never tested against chance = 1/points:
    the question is whether people lean to one side of neutral.
    """

    neutral: float
    above: int
    below: int
    at: int
    p_value: float | None
    median: float
    method: str = "exact two-sided sign test against the neutral value"

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def versus_neutral(values: Sequence[float], *, neutral: float) -> VersusNeutral | None:
    """How ``values`` sit around ``neutral``; ``None`` for no values."""
    if not values:
        return None
    above = sum(v > neutral for v in values)
    below = sum(v < neutral for v in values)
    sided = above + below
    return VersusNeutral(
        neutral=neutral,
        above=above,
        below=below,
        at=len(values) - sided,
        p_value=float(scipy.stats.binomtest(above, sided, 0.5).pvalue) if sided else None,
        median=float(statistics.median(values)),
    )


def mean(values: Sequence[float]) -> float | None:
    """The mean, or ``None`` for no values."""
    return statistics.fmean(values) if values else None


def median(values: Sequence[float]) -> float | None:
    """The median, or ``None`` for no values."""
    return float(statistics.median(values)) if values else None


def paper_figures() -> list[dict[str, Any]]:
    """The paper's two results with the statistics the survey's own results get."""
    return [
        {"question": question, "claim": claim, **_exact(k, n, chance=0.5).to_json()}
        for question, claim, k, n in PAPER_FIGURES
    ]
