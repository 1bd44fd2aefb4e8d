"""The statistics behind the verdict (:mod:`engine.verdict`): the exact permutation test, the
crossed bootstrap interval, the AUC, and the smallest Δ a design can detect.

All of them work on *per-seed* contested agreement (CA): one number per run, the share of the
contested matches it keeps. Seeds are the unit of replication; matches are crossed with seeds
(every run plays the same matches), which is why the bootstrap resamples both.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np
import scipy

#: Permutations for a Monte Carlo test when the exact one has more arrangements than this.
N_PERMUTATIONS = 9999

#: Simulated designs per Δ in :func:`min_detectable_delta` (power within about ±0.02).
N_POWER_SIMULATIONS = 400


def mean_difference(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    """The difference of the two samples' means along ``axis`` (scipy's vectorised form)."""
    diff: np.ndarray = np.mean(x, axis=axis) - np.mean(y, axis=axis)
    return diff


def permutation_p(
    advised: np.ndarray,
    baseline: np.ndarray,
    rng: np.random.Generator,
    n_resamples: int = N_PERMUTATIONS,
) -> np.ndarray:
    """Two-sided permutation p-value of the difference in mean CA.

    Exact (every relabelling of the seeds) when there are at most ``n_resamples`` of them, as
    scipy enumerates them then; Monte Carlo with ``rng`` otherwise.

    Args:
        advised: per-seed CA, shape ``(..., k_advised)``; leading axes are independent designs.
        baseline: per-seed CA, shape ``(..., k_baseline)``.
        rng: draws the relabellings of a Monte Carlo test.
        n_resamples: the largest number of relabellings to enumerate or draw.

    Returns:
        p-values of shape ``(...)``.
    """
    result = scipy.stats.permutation_test(
        (advised, baseline),
        mean_difference,
        permutation_type="independent",
        alternative="two-sided",
        vectorized=True,
        axis=-1,
        n_resamples=n_resamples,
        rng=rng,
    )
    return np.asarray(result.pvalue)


def smallest_p(k_advised: int, k_baseline: int, n_resamples: int = N_PERMUTATIONS) -> float:
    """The smallest two-sided p-value the permutation test can give with these seeds.

    The most extreme arrangement is one of ``C(k_a + k_b, k_a)`` and scipy doubles the smaller
    tail, so an exact test never goes below ``2 / C``: 0.1 for 3 seeds against 3. A Monte
    Carlo test counts the observed arrangement too: ``2 / (n_resamples + 1)``.
    """
    if k_advised < 1 or k_baseline < 1:
        return 1.0
    arrangements = math.comb(k_advised + k_baseline, k_advised)
    return min(1.0, 2 / min(arrangements, n_resamples + 1))


def auc(advised: np.ndarray, baseline: np.ndarray) -> float:
    """P(an advised seed's CA > a baseline seed's CA), ties counted half: Mann-Whitney U over
    ``k_advised * k_baseline``."""
    return float(auc_rows(np.asarray(advised), np.asarray(baseline)))


def auc_rows(advised: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """:func:`auc` along the last axis of every row at once, shape ``(...)``: Mann-Whitney's
    U statistic counted directly (scipy's ``mannwhitneyu`` costs milliseconds a call, and a
    bootstrap calls it thousands of times).

    Args:
        advised: shape ``(..., k_a)``.
        baseline: shape ``(..., k_b)``, leading axes broadcast against ``advised``'s.
    """
    a, b = advised[..., :, None], baseline[..., None, :]
    found: np.ndarray = ((a > b) + 0.5 * (a == b)).mean(axis=(-2, -1))
    return found


def crossed_bootstrap(
    kept_advised: np.ndarray,
    kept_baseline: np.ndarray,
    rng: np.random.Generator,
    n_boot: int = 2000,
    level: float = 0.95,
) -> tuple[float, float]:
    """Percentile interval of Δ resampling seeds (within each arm) and matches in every draw.

    Written with numpy because neither library resamples a crossed design:
    ``scipy.stats.bootstrap`` resamples each sample's observations independently, so it cannot
    share one resample of the matches between the two arms' columns, and rliable's stratified
    bootstrap resamples runs within fixed tasks (its tasks are never resampled).

    Args:
        kept_advised: 1 where an advised seed keeps a contested match, shape ``(k_a, n)``.
        kept_baseline: the same for the baseline seeds, shape ``(k_b, n)``.
        rng: draws the resamples.
        n_boot: bootstrap draws.
        level: the interval's coverage.
    """
    n = kept_advised.shape[1]
    matches = _weights(rng.integers(0, n, size=(n_boot, n)), n)
    deltas = _arm_means(kept_advised, matches, rng) - _arm_means(kept_baseline, matches, rng)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(deltas, [tail, 100 - tail])
    return float(low), float(high)


def _weights(draws: np.ndarray, size: int) -> np.ndarray:
    """Each row's resampled indices as weights summing to 1, shape ``(n_boot, size)``."""
    rows = np.arange(draws.shape[0])[:, None] * size  # one bincount for every row at once
    counts = np.bincount((draws + rows).ravel(), minlength=draws.shape[0] * size)
    weights: np.ndarray = counts.reshape(draws.shape[0], size) / draws.shape[1]
    return weights


def _arm_means(kept: np.ndarray, matches: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Mean CA of one arm per draw: resampled seeds times resampled matches."""
    k = kept.shape[0]
    seeds = _weights(rng.integers(0, k, size=(matches.shape[0], k)), k)
    means: np.ndarray = np.einsum("bi,ij,bj->b", seeds, kept.astype(np.float64), matches)
    return means


def min_detectable_delta(
    n_matches: int,
    k_advised: int,
    k_baseline: int,
    *,
    alpha: float = 0.05,
    power: float = 0.8,
    seed_sd: float = 0.1,
    seed: int = 0,
) -> float | None:
    """The smallest Δ that the verdict's test detects with probability ``power``.

    A seeded simulation of the test itself (the exact test is too discrete at a few seeds for
    a normal approximation: 4 seeds against 4 can reach p = 0.029, 3 against 3 never 0.05).
    Each simulated design draws, per seed, a true agreement ``p_arm + e`` with
    ``e ~ Normal(0, seed_sd)`` (seeds differ beyond the coin flips of the matches), clipped to
    [0, 1], and keeps each of ``n_matches`` contested matches with that probability. The arms'
    agreements straddle 1/2 (``0.5 ± Δ/2``), where a match's binomial variance is largest, so
    the answer is conservative. Power is found for Δ by bisection with the same random numbers
    for every Δ, and the result is rounded up to 0.01.

    Args:
        n_matches: informative contested matches.
        k_advised: advised seeds.
        k_baseline: baseline evaluation seeds.
        alpha: the test's two-sided level.
        power: the probability of rejecting that Δ must reach.
        seed_sd: between-seed spread of the true agreement.
        seed: seeds the simulation, so the form and the verdict print the same number.

    Returns:
        Δ in (0, 1], or None when even Δ = 1 is detected less often than ``power`` (too few
        matches or seeds).
    """
    if n_matches < 1 or smallest_p(k_advised, k_baseline) > alpha:
        return None
    return _mde(n_matches, k_advised, k_baseline, alpha, power, seed_sd, seed)


@lru_cache(maxsize=256)
def _mde(
    n: int, k_a: int, k_b: int, alpha: float, power: float, seed_sd: float, seed: int
) -> float | None:
    rng = np.random.default_rng(seed)
    shape_a, shape_b = (N_POWER_SIMULATIONS, k_a), (N_POWER_SIMULATIONS, k_b)
    noise = rng.normal(0, seed_sd, shape_a), rng.normal(0, seed_sd, shape_b)
    coins = rng.random(shape_a + (n,)), rng.random(shape_b + (n,))

    def detected(delta: float) -> bool:
        ca_a = (coins[0] < np.clip(0.5 + delta / 2 + noise[0], 0, 1)[..., None]).mean(-1)
        ca_b = (coins[1] < np.clip(0.5 - delta / 2 + noise[1], 0, 1)[..., None]).mean(-1)
        p = permutation_p(ca_a, ca_b, np.random.default_rng(seed), n_resamples=999)
        return bool(np.mean(p <= alpha) >= power)

    return smallest_detected(detected, 1.0)


def smallest_detected(detected: Callable[[float], bool], largest: float) -> float | None:
    """The smallest Δ in ``(0, largest]`` that ``detected`` accepts, by bisection (power
    rises with Δ), rounded up to 0.01; None when even ``largest`` is not detected."""
    if not detected(largest):
        return None
    low, high = 0.0, largest
    while high - low > 0.005:
        mid = (low + high) / 2
        low, high = (low, mid) if detected(mid) else (mid, high)
    return min(largest, math.ceil(high * 100) / 100)


def min_detectable_shift(
    k_advised: int,
    k_baseline: int,
    *,
    alpha: float = 0.05,
    power: float = 0.8,
    seed_sd: float = 0.2,
    largest: float = 2.0,
    seed: int = 0,
) -> float | None:
    """The smallest difference of per-seed means that the exact permutation test detects
    with probability ``power``, when each seed's value is its arm's mean plus
    ``Normal(0, seed_sd)``: the whole-bracket verdict's (:mod:`engine.verdict_bracket`),
    whose per-seed value is already an average over the bracket's candidates.

    Args:
        k_advised: advised seeds.
        k_baseline: baseline seeds.
        alpha: the test's two-sided level.
        power: the probability of rejecting that the difference must reach.
        seed_sd: between-seed spread of the per-seed value.
        largest: the largest difference the statistic can take (2 for a correlation).
        seed: seeds the simulation, so every caller prints the same number.

    Returns:
        The difference, or None when the exact test can never reach ``alpha`` or even
        ``largest`` is detected less often than ``power``.
    """
    if smallest_p(k_advised, k_baseline) > alpha:
        return None
    return _mds(k_advised, k_baseline, alpha, power, seed_sd, largest, seed)


@lru_cache(maxsize=256)
def _mds(
    k_a: int, k_b: int, alpha: float, power: float, seed_sd: float, largest: float, seed: int
) -> float | None:
    rng = np.random.default_rng(seed)
    noise_a = rng.normal(0, seed_sd, (N_POWER_SIMULATIONS, k_a))
    noise_b = rng.normal(0, seed_sd, (N_POWER_SIMULATIONS, k_b))

    def detected(delta: float) -> bool:
        p = permutation_p(noise_a + delta, noise_b, np.random.default_rng(seed), n_resamples=999)
        return bool(np.mean(p <= alpha) >= power)

    return smallest_detected(detected, largest)
