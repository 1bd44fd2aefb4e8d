"""The agent evaluation's statistics (issue 41 §2): which arm's agents win more often.

Declared before any evaluation is run (issue 41 §2, "declare which"; the outcome rule that
reads these is declared in :mod:`engine.evaluation.outcome`):

- **Unit.** A run (one trained agent). Answers of every evaluator pool per run: a run's **win
  rate over all opponents** is its wins (a "can't tell" counts 1/2) over the answers it took
  part in, within-arm answers included.
- **Statistic.** The advised arm's mean win rate minus the baseline arm's, over the runs that
  have answers. Under no difference it is near 0 (within-arm answers pull both means to 1/2).
- **p.** Exact two-sided permutation over all ``C(n, k)`` assignments of the arm labels to
  the ``n`` runs with answers, ``k`` of them advised (Fisher's randomisation test; for equal
  arms the same p as ``scipy.stats.permutation_test(..., permutation_type="independent")``
  on the win rates). Per-run win rates do not depend on the labels, so every assignment is
  one matrix product. p is the share of assignments whose statistic is at least as far from
  0 as the observed one: at k = 5 there are 252 and the smallest p is 2/252.
- **Interval.** Percentile bootstrap (:func:`interval`): evaluators resampled (where there are
  several), then runs within each arm.
- **Shown beside it.** The advised agents' win rate in between-arm pairs, and the left-side
  win rate of within-arm pairs (1/2 without side bias), each with its count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations

import numpy as np

from engine.errors import InputError

#: Two statistics closer than this are equal (win rates are small-denominator fractions).
TOLERANCE = 1e-9
#: The most statistics :func:`exact_p` holds at once (designs x assignments).
CELLS = 4_000_000

#: Each field of :class:`Answers` and its dtype.
DTYPES: dict[str, type] = {
    "a": int,
    "b": int,
    "winner_is_a": float,
    "chose_left": bool,
    "evaluator": int,
}


@dataclass(frozen=True)
class Answers:
    """Every answer of an evaluation, one row per answer, all of shape ``(n,)``.

    Attributes:
        a: the pair's first run, int.
        b: the pair's second run, int.
        winner_is_a: 1.0 when ``a`` was chosen, 0.0 when ``b`` was, 0.5 for "can't tell".
        chose_left: True when the chosen run was on the left (ignored for "can't tell").
        evaluator: the evaluator's id, int.
    """

    a: np.ndarray
    b: np.ndarray
    winner_is_a: np.ndarray
    chose_left: np.ndarray
    evaluator: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in DTYPES.items():  # lists are accepted and stored as arrays
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=dtype))
        if np.ndim(self.a) != 1 or {np.shape(getattr(self, f)) for f in DTYPES} != {self.a.shape}:
            raise InputError("answers need flat arrays of one length")
        if not np.isin(self.winner_is_a, (0.0, 0.5, 1.0)).all():
            raise InputError("winner_is_a must be 1, 0 or 0.5 ('can't tell')")
        if (self.a == self.b).any() or (np.minimum(self.a, self.b) < 0).any():
            raise InputError("a pair needs two different runs, indices >= 0")

    @property
    def n(self) -> int:
        """The number of answers."""
        return int(np.shape(self.a)[0])


@dataclass(frozen=True)
class Rate:
    """A share and the answers it rests on (``rate`` is None without any)."""

    rate: float | None
    n: int


def win_counts(
    a: np.ndarray,
    b: np.ndarray,
    winner_is_a: np.ndarray,
    n_runs: int,
    weights: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Wins and answers per run, each answer weighted (``np.bincount`` over flat rows).

    Args:
        a, b, winner_is_a: shape ``(..., m)``; leading axes are independent designs/draws.
        n_runs: runs per design.
        weights: each answer's weight, broadcast against ``a`` (1 when None).

    Returns:
        ``(wins, answered)``, each of shape ``(..., n_runs)``.
    """
    arrays = np.broadcast_arrays(a, b, winner_is_a, np.ones(()) if weights is None else weights)
    a, b, win, w = arrays
    lead = a.shape[:-1]
    rows = math.prod(lead)
    offset = (np.arange(rows) * n_runs).reshape(*lead, 1)

    def count(runs: np.ndarray, x: np.ndarray) -> np.ndarray:
        flat = np.bincount((runs + offset).ravel(), x.ravel(), minlength=rows * n_runs)
        return flat.reshape(*lead, n_runs)

    return count(a, w * win) + count(b, w * (1 - win)), count(a, w) + count(b, w)


def win_rates(answers: Answers, n_runs: int) -> np.ndarray:
    """Each run's win rate over all opponents, shape ``(n_runs,)``; nan without answers."""
    wins, answered = win_counts(answers.a, answers.b, answers.winner_is_a, n_runs)
    with np.errstate(invalid="ignore", divide="ignore"):
        rates: np.ndarray = wins / answered
    return rates


@lru_cache(maxsize=32)
def label_masks(n: int, k: int) -> np.ndarray:
    """Every assignment of ``k`` advised labels to ``n`` runs, bool ``(C(n, k), n)``."""
    masks = np.zeros((math.comb(n, k), n), dtype=bool)
    for row, chosen in enumerate(combinations(range(n), k)):
        masks[row, list(chosen)] = True
    masks.setflags(write=False)
    return masks


def exact_p(rates: np.ndarray, advised: np.ndarray) -> np.ndarray:
    """Two-sided exact permutation p of the declared statistic (module docstring).

    Args:
        rates: per-run win rates, shape ``(..., n)``, none nan; leading axes independent.
        advised: the arm labels, bool shape ``(n,)``, both arms non-empty.

    Returns:
        p-values, shape ``(...)``.
    """
    masks = label_masks(len(advised), int(advised.sum()))
    contrasts = masks / masks[0].sum() - ~masks / (~masks[0]).sum()  # (C, n)
    flat = np.reshape(rates, (-1, len(advised)))
    observed = np.abs(flat @ (advised / advised.sum() - ~advised / (~advised).sum()))
    found = np.empty(len(flat))
    step = max(1, CELLS // len(contrasts))  # rows per chunk, so no chunk holds more cells
    for start in range(0, len(flat), step):
        every = np.abs(flat[start : start + step] @ contrasts.T)
        found[start : start + step] = (
            every >= observed[start : start + step, None] - TOLERANCE
        ).mean(1)
    return found.reshape(np.shape(rates)[:-1])


def smallest_p(k_advised: int, k_baseline: int) -> float:
    """The smallest p :func:`exact_p` can give: the extreme assignment and, for equal arms,
    its mirror, over ``C(k_a + k_b, k_a)``."""
    return (2 if k_advised == k_baseline else 1) / math.comb(k_advised + k_baseline, k_advised)


def statistic(rates: np.ndarray, advised: np.ndarray) -> float | None:
    """The declared statistic from per-run win rates ``(n_runs,)`` (nan: no answers), or None
    when an arm has no run with answers."""
    present = ~np.isnan(rates)
    if not (advised & present).any() or not (~advised & present).any():
        return None
    return float(rates[advised & present].mean() - rates[~advised & present].mean())


def permutation_p(answers: Answers, advised: np.ndarray) -> float:
    """:func:`exact_p` over the runs that have answers (both arms need one)."""
    rates = win_rates(answers, len(advised))
    if statistic(rates, advised) is None:
        raise InputError("the permutation test needs a run with answers in each arm")
    present = ~np.isnan(rates)
    return float(exact_p(rates[present], advised[present]))


def _arm_means(rates: np.ndarray, runs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Mean win rate of ``len(runs)`` runs drawn with replacement from ``runs``, per row of
    ``rates`` ``(B, n_runs)``; runs without answers in a draw are left out (nan if all)."""
    drawn = np.take_along_axis(
        rates, runs[rng.integers(0, len(runs), rates.shape[:1] + runs.shape)], 1
    )
    ok = ~np.isnan(drawn)
    with np.errstate(invalid="ignore", divide="ignore"):
        means: np.ndarray = np.where(ok, drawn, 0).sum(axis=1) / ok.sum(axis=1)
    return means


def _evaluator_weights(evaluator: np.ndarray, rng: np.random.Generator, n_boot: int) -> np.ndarray:
    """Each answer's weight in each draw, shape ``(n_boot, n)``: how often its evaluator was
    drawn among as many drawn with replacement (all 1 with one evaluator)."""
    uniq, which = np.unique(evaluator, return_inverse=True)
    if len(uniq) == 1:
        return np.ones((n_boot, len(evaluator)))
    drawn = rng.multinomial(len(uniq), np.full(len(uniq), 1 / len(uniq)), n_boot)
    return np.asarray(drawn[:, which], dtype=float)


def interval(
    answers: Answers,
    advised: np.ndarray,
    rng: np.random.Generator,
    n_boot: int = 2000,
    level: float = 0.95,
) -> tuple[float, float]:
    """Percentile bootstrap interval of the statistic (issue 41 §2, "Pooling and interval").

    Each of ``n_boot`` draws: (1) where there are several evaluators, draw as many with
    replacement and weight each answer by how often its evaluator was drawn; (2) recompute every
    run's win rate from those weighted answers; (3) within each arm, draw as many runs (of those
    with answers) with replacement and take the difference of the arms' mean win rates. A run
    left without answers by step 1 drops out of its arm's mean in that draw. Written with numpy:
    ``scipy.stats.bootstrap`` resamples one level, not evaluators crossed with runs.
    """
    observed = win_rates(answers, len(advised))
    if statistic(observed, advised) is None:
        raise InputError("the interval needs a run with answers in each arm")
    present = ~np.isnan(observed)
    weights = _evaluator_weights(answers.evaluator, rng, n_boot)
    wins, answered = win_counts(answers.a, answers.b, answers.winner_is_a, len(advised), weights)
    with np.errstate(invalid="ignore", divide="ignore"):
        rates = wins / answered
    draws = _arm_means(rates, np.flatnonzero(advised & present), rng) - _arm_means(
        rates, np.flatnonzero(~advised & present), rng
    )
    low, high = np.nanquantile(draws, [(1 - level) / 2, (1 + level) / 2])
    return float(low), float(high)


def side_bias(answers: Answers, advised: np.ndarray) -> Rate:
    """The left-side win rate of within-arm answers ("can't tell" counts 1/2); 1/2 unbiased."""
    within = advised[answers.a] == advised[answers.b]
    left = np.where(answers.winner_is_a == 0.5, 0.5, answers.chose_left.astype(float))[within]
    return Rate(float(left.mean()) if left.size else None, int(left.size))


def between_arm_win_rate(answers: Answers, advised: np.ndarray) -> Rate:
    """The advised runs' win rate in between-arm answers ("can't tell" counts 1/2)."""
    between = advised[answers.a] != advised[answers.b]
    won = np.where(advised[answers.a], answers.winner_is_a, 1 - answers.winner_is_a)[between]
    return Rate(float(won.mean()) if won.size else None, int(won.size))
