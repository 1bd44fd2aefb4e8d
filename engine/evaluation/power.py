"""How many evaluators and answers the evaluation needs (issue 41 §2 "Shown" and §4 "Power").

By simulation of the exact design and test:

- ``2k`` runs, the first ``k`` advised; each run's propensity is ``N(0, run_sd)`` on the logit
  scale (run effects, :data:`engine.evaluation.simulate.RUN_SD`), plus ``delta`` for the
  advised runs, where ``delta`` (:func:`arm_effect`) makes the expected advised win
  probability in a between-arm pair equal ``win_rate``: ``E[expit(delta + e)] = win_rate``
  with ``e ~ N(0, 2 run_sd^2)``, by Gauss-Hermite quadrature and Brent's root finder;
- the pairs of :func:`engine.evaluation.design.pair_sequence`, ``pairs_per_evaluator`` per
  evaluator, answered by a Bradley-Terry evaluator on those propensities;
- power is the share of designs where :mod:`engine.evaluation.outcome` says "more" (or "less"
  for ``win_rate < 1/2``).

Every count of evaluators reads the first answers of the same simulated designs (common random
numbers), so power grows smoothly with the count and a search over counts is monotone but for
Monte Carlo noise (about ±0.02 at 400 designs).

Pairs per evaluator matter here only through the total of answers: evaluator ``e`` answers
positions ``e * m ..`` of one sequence, so E evaluators of m pairs answer the same pairs as any
other split of ``E * m``, and the simulated evaluators are alike (no evaluator effects).

**What the table says** (measured, ``power_table(w, 5, RUN_SD, 20, (1, 2, 5, 10, 20, 50),
np.random.default_rng(0), n_sims=1000)``, RUN_SD = 0.685 from round 1's ``n1`` seeds):

===========  =====  =====  =====  =====  =====  =====
win rate      1      2      5      10     20     50     (evaluators; x 20 answers)
===========  =====  =====  =====  =====  =====  =====
0.65         0.08   0.12   0.21   0.25   0.26   0.31
0.75         0.20   0.32   0.52   0.63   0.68   0.72
0.80         0.28   0.48   0.72   0.82   0.86   0.89
0.85         0.42   0.68   0.89   0.95   0.96   0.98
===========  =====  =====  =====  =====  =====  =====

With 5 runs per arm and the run spread of round 1, a win rate of 0.65 is **not** detectable at
80% power by any number of answers: power levels off near 0.31 (runs, not answers, are the
unit). The smallest win rate the default design (20 pairs per participant) detects at 80% is
about 0.80, with 10 participants (200 answers; 0.85 needs 4). Without run effects
(``run_sd = 0``) 0.65 needs 12 participants (240 answers). So 20 pairs per participant is kept
(power depends on the total, and 20 pairs is one round-robin stretch of 4 matchings at 10
runs, each run shown 4 times); detecting 0.65 needs more runs per arm, not more answers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy
from scipy.special import expit

from engine.errors import InputError
from engine.evaluation.simulate import DesignBatch, NoisyTeacher, outcome_signs, simulate_designs

#: The most evaluators a design is sized to (:func:`answers_needed` searches up to it).
MAX_EVALUATORS = 100
#: Simulated designs per count of evaluators (power within about ±0.02).
N_POWER_SIMULATIONS = 400
#: Gauss-Hermite (probabilists') nodes for :func:`arm_effect`.
_NODES, _WEIGHTS = np.polynomial.hermite_e.hermegauss(60)


@dataclass(frozen=True)
class PowerTable:
    """Power by number of evaluators, for one design.

    Attributes:
        evaluators: evaluator counts, int ``(m,)``.
        answers: answers at each count (evaluators x pairs per evaluator), int ``(m,)``.
        power: the share of simulated designs detecting the effect, float ``(m,)``.
        win_rate: the declared between-arm advised win probability.
        k: runs per arm.
        run_sd: the run effects' sd on the logit scale.
        pairs_per_evaluator: pairs each evaluator answers.
        n_sims: simulated designs behind each power.
    """

    evaluators: np.ndarray
    answers: np.ndarray
    power: np.ndarray
    win_rate: float
    k: int
    run_sd: float
    pairs_per_evaluator: int
    n_sims: int


@dataclass(frozen=True)
class AnswersNeeded:
    """The smallest design reaching the power asked for.

    Attributes:
        evaluators: the fewest evaluators reaching ``power`` (None when ``max_evaluators``
            does not: runs, not answers, limit the design).
        answers: ``evaluators * pairs_per_evaluator`` (None with ``evaluators``).
        power: the simulated power at ``evaluators`` (at ``max_evaluators`` when None).
        target: the power asked for.
    """

    evaluators: int | None
    answers: int | None
    power: float
    target: float


def arm_effect(win_rate: float, run_sd: float) -> float:
    """The advised runs' logit shift ``delta`` that makes the expected between-arm advised
    win probability ``win_rate`` under run effects (module docstring)."""
    if not 0 < win_rate < 1:
        raise InputError(f"win_rate must be in (0, 1), got {win_rate}")
    spread = np.sqrt(2.0) * run_sd * _NODES
    weights = _WEIGHTS / _WEIGHTS.sum()

    def gap(delta: float) -> float:
        return float(weights @ expit(delta + spread)) - win_rate

    return float(scipy.optimize.brentq(gap, -50.0, 50.0, xtol=1e-12))


def _simulate(
    win_rate: float,
    k: int,
    run_sd: float,
    n_answers: int,
    rng: np.random.Generator,
    n_sims: int,
) -> DesignBatch:
    """``n_sims`` designs of ``n_answers`` answers under the declared effect."""
    if k < 2 or n_answers < 1 or n_sims < 1 or run_sd < 0:
        raise InputError("power needs k >= 2, answers >= 1, simulations >= 1, run_sd >= 0")
    advised = np.arange(2 * k) < k
    scores = rng.normal(0.0, run_sd, (n_sims, 2 * k)) + arm_effect(win_rate, run_sd) * advised
    return simulate_designs(scores, advised, n_answers, NoisyTeacher(), rng)


def _power(batch: DesignBatch, n_answers: int, win_rate: float, alpha: float) -> float:
    """The share of designs whose first ``n_answers`` say the effect's direction."""
    signs = outcome_signs(batch.head(n_answers), alpha)
    return float((signs == (1 if win_rate >= 0.5 else -1)).mean())


def power_table(
    win_rate: float,
    k: int,
    run_sd: float,
    pairs_per_evaluator: int,
    evaluator_counts: Sequence[int],
    rng: np.random.Generator,
    alpha: float = 0.05,
    n_sims: int = N_POWER_SIMULATIONS,
) -> PowerTable:
    """Power at each count of evaluators (module docstring).

    Args:
        win_rate: the declared between-arm advised win probability (e.g. 0.65).
        k: runs per arm.
        run_sd: the run effects' sd on the logit scale.
        pairs_per_evaluator: pairs each evaluator answers (the product's default is 20).
        evaluator_counts: the counts to tabulate, each at least 1.
        rng: draws the simulated designs.
        alpha: the test's level.
        n_sims: simulated designs (shared by every count).
    """
    counts = np.asarray(sorted(evaluator_counts), dtype=int)
    if counts.size == 0 or counts[0] < 1:
        raise InputError("evaluator counts must be at least 1")
    answers = counts * pairs_per_evaluator
    batch = _simulate(win_rate, k, run_sd, int(answers[-1]), rng, n_sims)
    power = np.array([_power(batch, int(n), win_rate, alpha) for n in answers])
    return PowerTable(counts, answers, power, win_rate, k, run_sd, pairs_per_evaluator, n_sims)


def answers_needed(
    win_rate: float,
    k: int,
    run_sd: float,
    pairs_per_evaluator: int,
    rng: np.random.Generator,
    power: float = 0.8,
    alpha: float = 0.05,
    max_evaluators: int = MAX_EVALUATORS,
    n_sims: int = N_POWER_SIMULATIONS,
) -> AnswersNeeded:
    """The fewest evaluators (and answers) whose simulated power reaches ``power``.

    Bisection over ``1 .. max_evaluators`` on one set of simulated designs (module docstring).
    With run effects, more answers cannot make up for too few runs: when even
    ``max_evaluators`` fall short, ``evaluators`` is None and ``power`` is the ceiling reached.

    Args:
        win_rate: the declared between-arm advised win probability (e.g. 0.65).
        k: runs per arm.
        run_sd: the run effects' sd on the logit scale.
        pairs_per_evaluator: pairs each evaluator answers.
        rng: draws the simulated designs.
        power: the power asked for.
        alpha: the test's level.
        max_evaluators: the largest count searched.
        n_sims: simulated designs.
    """
    m = pairs_per_evaluator
    batch = _simulate(win_rate, k, run_sd, max_evaluators * m, rng, n_sims)
    top = _power(batch, max_evaluators * m, win_rate, alpha)
    if top < power:
        return AnswersNeeded(None, None, top, power)
    low, high, reached = 0, max_evaluators, top  # power(low) < target <= power(high)
    while high - low > 1:
        mid = (low + high) // 2
        found = _power(batch, mid * m, win_rate, alpha)
        low, high, reached = (low, mid, found) if found >= power else (mid, high, reached)
    return AnswersNeeded(high, high * m, reached, power)
