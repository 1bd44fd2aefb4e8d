"""Which pairs of runs each evaluator is shown, and on which side (issue 41 §1, "Pairs over all
runs").

Pairs are drawn over **all** unordered pairs of the ``n`` runs of both arms, within-arm pairs
included (20 of the 45 pairs of 10 runs at k = 5), from one seeded endless sequence:

1. The sequence is made of *rounds*; a round holds every one of the ``C(n, 2)`` pairs once.
2. A round is a round-robin schedule (the circle method, Walecki's construction in Lucas,
   *Récréations mathématiques* II, 1883: a 1-factorisation of the complete graph, Harary,
   *Graph Theory*, 1969, ch. 9): ``n - 1`` matchings of ``n / 2`` disjoint pairs when ``n``
   is even, ``n`` matchings of ``(n - 1) / 2`` pairs (each run sitting one out) when it is
   odd. Each round relabels the runs at random, shuffles the order of its matchings and the
   pairs inside each, so the rounds are shuffled rounds of all pairs.
3. Evaluator ``e`` gets positions ``e * n_pairs .. (e + 1) * n_pairs - 1``.

So over evaluators every pair is shown equally often up to one round, and since matchings are
consecutive, any stretch of whole matchings shows every run equally often: at 10 runs and 20
pairs per evaluator (4 matchings), each evaluator sees each run exactly 4 times.

Sides are a fair coin per pair, seeded from the sequence's seed and the evaluator's index.
Rounds come in blocks of :data:`ROUNDS_PER_BLOCK`, each block from its own generator
``default_rng([seed, 0, block])`` and each evaluator's sides from ``default_rng([seed, 1,
e])``, so an evaluator's pairs never depend on how many evaluators come before or after.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from engine.errors import InputError

#: Rounds drawn from one generator (vectorised), the sequence's unit of seeding.
ROUNDS_PER_BLOCK = 8


@dataclass(frozen=True)
class PairPlan:
    """The pairs one evaluator is shown, in order.

    Attributes:
        a: the first run of each pair, ``a < b``, int shape ``(n_pairs,)``.
        b: the second run of each pair, int shape ``(n_pairs,)``.
        a_left: True where run ``a`` is shown on the left, bool shape ``(n_pairs,)``.
        evaluator: the evaluator's index in the sequence (0, 1, 2 ...).
    """

    a: np.ndarray
    b: np.ndarray
    a_left: np.ndarray
    evaluator: int


@lru_cache(maxsize=64)
def round_robin(n_runs: int) -> np.ndarray:
    """The circle method's schedule over runs ``0 .. n_runs-1`` (module docstring, step 2).

    Returns:
        int array of shape ``(n_matchings, n_runs // 2, 2)``: every unordered pair exactly
        once, the pairs of a matching disjoint, each pair as ``(smaller, larger)``.
    """
    m = n_runs if n_runs % 2 == 0 else n_runs + 1  # an odd count gets a dummy "bye" run
    fixed, others = m - 1, np.arange(m - 1)
    rounds = []
    for r in range(m - 1):
        i = np.arange(1, m // 2)
        left = np.concatenate([[fixed], (r + i) % (m - 1)])
        right = np.concatenate([[others[r]], (r - i) % (m - 1)])
        pairs = np.stack([left, right], axis=1)
        rounds.append(pairs[(pairs < n_runs).all(axis=1)])
    schedule: np.ndarray = np.sort(np.stack(rounds), axis=2)
    schedule.setflags(write=False)
    return schedule


def _block(n_runs: int, rng_seed: int, block: int) -> np.ndarray:
    """:data:`ROUNDS_PER_BLOCK` shuffled rounds, int shape ``(rounds * C(n, 2), 2)``."""
    rng = np.random.default_rng([rng_seed, 0, block])
    schedule = round_robin(n_runs)
    n_matchings, per, _ = schedule.shape
    r = ROUNDS_PER_BLOCK
    labels = rng.permuted(np.tile(np.arange(n_runs), (r, 1)), axis=1)
    order = rng.permuted(np.tile(np.arange(n_matchings), (r, 1)), axis=1)
    within = rng.permuted(np.tile(np.arange(per), (r, n_matchings, 1)), axis=2)
    pairs = schedule[order[:, :, None], within]  # (r, n_matchings, per, 2)
    relabelled = np.take_along_axis(labels, pairs.reshape(r, -1), axis=1)
    return np.sort(relabelled.reshape(-1, 2), axis=1)


def pair_sequence(n_runs: int, start: int, stop: int, rng_seed: int) -> np.ndarray:
    """Positions ``start .. stop-1`` of the seeded endless sequence of pairs.

    Returns:
        int array of shape ``(stop - start, 2)``, each row ``(a, b)`` with ``a < b``.
    """
    per_block = ROUNDS_PER_BLOCK * math.comb(n_runs, 2)
    first, last = start // per_block, (stop - 1) // per_block
    pairs = np.concatenate([_block(n_runs, rng_seed, j) for j in range(first, last + 1)])
    offset = start - first * per_block
    return pairs[offset : offset + stop - start]


def evaluator_pairs(n_runs: int, n_pairs: int, evaluator: int, rng_seed: int) -> PairPlan:
    """The pairs evaluator ``evaluator`` is shown: the next ``n_pairs`` of the sequence.

    Deterministic given its arguments (module docstring).

    Args:
        n_runs: runs over both arms (``2k``), at least 2.
        n_pairs: pairs per evaluator, at least 1.
        evaluator: the evaluator's index, 0 for the first one to start.
        rng_seed: the evaluation's seed (a non-negative integer).

    Raises:
        InputError: (a ValueError) on a count, index or seed out of range.
    """
    if n_runs < 2:
        raise InputError(f"an evaluation needs at least 2 runs, got {n_runs}")
    if n_pairs < 1:
        raise InputError(f"an evaluator needs at least 1 pair, got {n_pairs}")
    if evaluator < 0 or rng_seed < 0:
        raise InputError(f"evaluator and seed must be >= 0, got {evaluator} and {rng_seed}")
    pairs = pair_sequence(n_runs, evaluator * n_pairs, (evaluator + 1) * n_pairs, rng_seed)
    a_left = np.random.default_rng([rng_seed, 1, evaluator]).random(n_pairs) < 0.5
    return PairPlan(a=pairs[:, 0], b=pairs[:, 1], a_left=a_left, evaluator=evaluator)
