"""Simulated evaluators and the synthetic null (issue 41 §4).

Simulated evaluators check the statistics and the plumbing, not that people see the
difference: a teacher judging pairs is a noisy re-measurement of its own score.

**Run effects.** Each run has a win propensity on the logit scale: an evaluator prefers run
``a`` to ``b`` with probability ``expit(s_a - s_b)`` (Bradley-Terry), ``s`` a run's score over
:data:`U_SCALE`. Between seeds of one arm the propensity varies with sd :data:`RUN_SD`,
measured from round 1's ``n1`` seeds (below). Runs, not answers, are then the unit of
replication, so a test that counts answers as independent (a binomial test on the between-arm
answers, :func:`naive_fires`) fires far above its level under a null with run effects, while
the exact permutation over runs (:mod:`engine.evaluation.stats`) keeps it.

Batches of designs are simulated at once (:class:`DesignBatch`): the pairs of the real design
(:func:`engine.evaluation.design.pair_sequence`, one seed per design), sides a fair coin per
pair, and every evaluator of this module answers arrays as well as single pairs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import scipy
from scipy.special import expit

from engine.evaluation.design import PairPlan, pair_sequence
from engine.evaluation.stats import (
    Answers,
    exact_p,
    permutation_p,
    smallest_p,
    statistic,
    win_counts,
    win_rates,
)

#: The spread of U between ``n1`` (no-advice) seeds: the sample sd (ddof 1) of ``truth`` in
#: ``docs/validation/humanoid-orthogonal/measures/n1-{0..4}.json`` (round 1, Humanoid-v5, the
#: ``orthogonal`` teacher, 1M steps; U = 0.250, 0.299, 0.375, 0.238, 0.196; docs/validation.md
#: §1 and §5 "Humanoid-v5").
RUN_SD_U = 0.0685
#: Declared, not measured: the U difference that is one logit of preference, so an evaluator
#: prefers run a to b with probability ``expit((U_a - U_b) / U_SCALE)``; a tenth of U's range
#: [0, 1] makes the higher run win 73% of the time.
U_SCALE = 0.1
#: The run effects' sd on the logit scale: ``RUN_SD_U / U_SCALE``.
RUN_SD = RUN_SD_U / U_SCALE
#: A score or an array of them; a side or an array of sides (True: ``a`` on the left).
Scores = np.ndarray | float
Sides = np.ndarray | bool


class Evaluator(Protocol):
    """Answers pairs: 1.0 when it picks ``a``, 0.0 for ``b``, 0.5 for "can't tell"."""

    def answer(
        self, a_score: Scores, b_score: Scores, a_left: Sides, rng: np.random.Generator
    ) -> np.ndarray:
        """Answers of the broadcast shape of the inputs (0-d for one pair: ``float()`` it)."""
        ...


def _shape(*arrays: Scores | Sides) -> tuple[int, ...]:
    """The broadcast shape of the inputs."""
    return np.broadcast_shapes(*(np.shape(x) for x in arrays))


@dataclass(frozen=True)
class NoisyTeacher:
    """Bradley-Terry on its scores: picks ``a`` with probability ``expit((a - b) / scale)``."""

    scale: float = 1.0

    def answer(
        self, a_score: Scores, b_score: Scores, a_left: Sides, rng: np.random.Generator
    ) -> np.ndarray:
        """See :class:`Evaluator`."""
        p = expit((np.asarray(a_score) - b_score) / self.scale)
        return np.where(rng.random(_shape(a_score, b_score, a_left)) < p, 1.0, 0.0)


@dataclass(frozen=True)
class SideBias:
    """Picks the left run ``p_left`` of the time when ``inner`` is even: with probability
    ``|2 p_left - 1|`` it picks the favoured side whatever it sees, else asks ``inner``."""

    p_left: float = 0.65
    inner: Evaluator = field(default_factory=NoisyTeacher)

    def answer(
        self, a_score: Scores, b_score: Scores, a_left: Sides, rng: np.random.Generator
    ) -> np.ndarray:
        """See :class:`Evaluator`."""
        shape = _shape(a_score, b_score, a_left)
        side = np.where(np.asarray(a_left) == (self.p_left >= 0.5), 1.0, 0.0)
        biased = rng.random(shape) < abs(2 * self.p_left - 1)
        return np.where(biased, side, self.inner.answer(a_score, b_score, a_left, rng))


@dataclass(frozen=True)
class Lapses:
    """A fair coin instead of ``inner``'s answer ``rate`` of the time (attention lapses)."""

    rate: float = 0.2
    inner: Evaluator = field(default_factory=NoisyTeacher)

    def answer(
        self, a_score: Scores, b_score: Scores, a_left: Sides, rng: np.random.Generator
    ) -> np.ndarray:
        """See :class:`Evaluator`."""
        shape = _shape(a_score, b_score, a_left)
        coin = np.where(rng.random(shape) < 0.5, 1.0, 0.0)
        lapsed = rng.random(shape) < self.rate
        return np.where(lapsed, coin, self.inner.answer(a_score, b_score, a_left, rng))


@dataclass(frozen=True)
class CantTellWhenClose:
    """Says "can't tell" (0.5) when the scores differ by less than ``threshold`` (in the
    scores' own units), else asks ``inner``."""

    threshold: float = 0.5
    inner: Evaluator = field(default_factory=NoisyTeacher)

    def answer(
        self, a_score: Scores, b_score: Scores, a_left: Sides, rng: np.random.Generator
    ) -> np.ndarray:
        """See :class:`Evaluator`."""
        close = np.abs(np.asarray(a_score) - b_score) < self.threshold
        return np.where(close, 0.5, self.inner.answer(a_score, b_score, a_left, rng))


def _chose_left(winner: np.ndarray, a_left: np.ndarray) -> np.ndarray:
    """Whether the chosen run was on the left (False for "can't tell")."""
    chosen: np.ndarray = np.where(winner == 1.0, a_left, ~a_left) & (winner != 0.5)
    return chosen


def simulate_answers(
    scores_per_run: np.ndarray,
    plans: Sequence[PairPlan],
    evaluators: Evaluator | Sequence[Evaluator],
    rng: np.random.Generator,
) -> Answers:
    """One evaluation's answers: each plan's evaluator answers its pairs.

    Args:
        scores_per_run: each run's score on its evaluators' scale, shape ``(n_runs,)``.
        plans: one per evaluator (:func:`engine.evaluation.design.evaluator_pairs`).
        evaluators: one for every plan, or one per plan.
        rng: draws the answers.
    """
    many = evaluators if isinstance(evaluators, Sequence) else [evaluators] * len(plans)
    parts = []
    for plan, who in zip(plans, many, strict=True):
        s_a, s_b = scores_per_run[plan.a], scores_per_run[plan.b]
        winner = np.asarray(who.answer(s_a, s_b, plan.a_left, rng), dtype=float)
        chosen = _chose_left(winner, plan.a_left)
        parts.append((plan.a, plan.b, winner, chosen, np.full(len(plan.a), plan.evaluator)))
    return Answers(*(np.concatenate(column) for column in zip(*parts, strict=True)))


@dataclass(frozen=True)
class DesignBatch:
    """``D`` simulated evaluations of one design, ``m`` answers each.

    Attributes:
        a: first run of each pair, int ``(D, m)``.
        b: second run, int ``(D, m)``.
        a_left: run ``a`` shown on the left, bool ``(D, m)``.
        winner_is_a: the answers (1, 0 or 0.5), float ``(D, m)``.
        advised: the arm labels, bool ``(n_runs,)``.
    """

    a: np.ndarray
    b: np.ndarray
    a_left: np.ndarray
    winner_is_a: np.ndarray
    advised: np.ndarray

    def head(self, m: int) -> DesignBatch:
        """The first ``m`` answers of every design (fewer evaluators, the same draws)."""
        cut = (self.a[:, :m], self.b[:, :m], self.a_left[:, :m], self.winner_is_a[:, :m])
        return DesignBatch(*cut, advised=self.advised)

    def answers(self, design: int) -> Answers:
        """Design ``design`` as :class:`Answers` (one evaluator id: 0)."""
        w, left = self.winner_is_a[design], self.a_left[design]
        zeros = np.zeros(len(w), dtype=int)
        return Answers(self.a[design], self.b[design], w, _chose_left(w, left), zeros)


def simulate_designs(
    scores: np.ndarray,
    advised: np.ndarray,
    n_answers: int,
    evaluator: Evaluator,
    rng: np.random.Generator,
) -> DesignBatch:
    """Answer ``n_answers`` pairs of the design in each of ``D`` evaluations at once.

    Args:
        scores: each run's score per design, shape ``(D, n_runs)``.
        advised: the arm labels, bool ``(n_runs,)``.
        n_answers: answers per design (evaluators x pairs per evaluator).
        evaluator: answers every pair.
        rng: draws each design's pair seed, the sides and the answers.
    """
    n_designs, n_runs = scores.shape
    seeds: list[int] = np.asarray(rng.integers(0, 2**63, n_designs)).tolist()
    pairs = np.stack([pair_sequence(n_runs, 0, n_answers, s) for s in seeds])
    a, b = pairs[..., 0], pairs[..., 1]
    a_left = rng.random(a.shape) < 0.5
    s_a, s_b = np.take_along_axis(scores, a, 1), np.take_along_axis(scores, b, 1)
    winner = np.asarray(evaluator.answer(s_a, s_b, a_left, rng), dtype=float)
    return DesignBatch(a, b, a_left, winner, np.asarray(advised, dtype=bool))


def outcome_signs(batch: DesignBatch, alpha: float = 0.05) -> np.ndarray:
    """What :func:`engine.evaluation.outcome.evaluate` says per design, int ``(D,)``: +1
    "more", -1 "less", 0 otherwise (rules 1-2; the interval never makes more or less).

    Designs where every run has answers are tested at once; the others one by one.
    """
    advised = batch.advised
    wins, answered = win_counts(batch.a, batch.b, batch.winner_is_a, len(advised))
    full = (answered > 0).all(axis=1)
    k_a, k_b = int(advised.sum()), int((~advised).sum())
    p, stat = np.ones(full.shape), np.zeros(full.shape)
    if full.any() and min(k_a, k_b) >= 2 and smallest_p(k_a, k_b) < alpha:
        rates = wins[full] / answered[full]
        p[full] = exact_p(rates, advised)
        stat[full] = rates[:, advised].mean(axis=1) - rates[:, ~advised].mean(axis=1)
    for design in np.flatnonzero(~full).tolist():
        p[design], stat[design] = _one(batch.answers(design), advised, alpha)
    signs: np.ndarray = np.where(p < alpha, np.sign(stat), 0).astype(int)
    return signs


def _one(answers: Answers, advised: np.ndarray, alpha: float) -> tuple[float, float]:
    """``(p, statistic)`` of one design with runs lacking answers; p is 1.0 where rule 1
    forbids a decision."""
    rates = win_rates(answers, len(advised))
    present = ~np.isnan(rates)
    k_a, k_b = int((advised & present).sum()), int((~advised & present).sum())
    if min(k_a, k_b) < 2 or smallest_p(k_a, k_b) >= alpha:
        return 1.0, 0.0
    return permutation_p(answers, advised), float(statistic(rates, advised) or 0.0)


def naive_fires(batch: DesignBatch, alpha: float = 0.05) -> np.ndarray:
    """A test that ignores clustering by run, per design, bool ``(D,)``: the exact binomial
    test (``scipy.stats.binomtest``, two-sided) of the advised runs' wins in between-arm
    answers against 1/2, "can't tell" answers dropped."""
    adv_a, adv_b = batch.advised[batch.a], batch.advised[batch.b]
    decided = (adv_a != adv_b) & (batch.winner_is_a != 0.5)
    advised_won = decided & ((batch.winner_is_a == 1.0) == adv_a)
    n, won = decided.sum(axis=1), advised_won.sum(axis=1)
    return np.array(
        [
            n_i > 0 and scipy.stats.binomtest(int(w), int(n_i)).pvalue < alpha
            for w, n_i in zip(won, n, strict=True)
        ]
    )


def null_designs(
    rng: np.random.Generator,
    n_designs: int = 1000,
    k: int = 5,
    run_sd: float = RUN_SD,
    evaluator: Evaluator | None = None,
    n_answers: int = 200,
) -> DesignBatch:
    """Designs where the arms do not differ but each run's propensity does: ``2k`` runs, the
    first ``k`` advised, scores ``N(0, run_sd)`` on the logit scale, answered by ``evaluator``
    (a :class:`NoisyTeacher` at scale 1 when None); 200 answers is 10 evaluators x 20 pairs."""
    scores = rng.normal(0.0, run_sd, (n_designs, 2 * k))
    advised = np.arange(2 * k) < k
    return simulate_designs(scores, advised, n_answers, evaluator or NoisyTeacher(), rng)


def synthetic_null_rate(
    rng: np.random.Generator,
    n_designs: int = 1000,
    k: int = 5,
    run_sd: float = RUN_SD,
    evaluator: Evaluator | None = None,
    n_answers: int = 200,
    alpha: float = 0.05,
) -> float:
    """The share of null designs (:func:`null_designs`) where the evaluation says "more" or
    "less" (issue 41 §4: at most 5% ± 1.5% over 1,000 designs)."""
    batch = null_designs(rng, n_designs, k, run_sd, evaluator, n_answers)
    return float((outcome_signs(batch, alpha) != 0).mean())
