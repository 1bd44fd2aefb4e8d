"""The verdict's statistics: exact test floor, crossed bootstrap, AUC, smallest detectable Δ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from engine.verdict_power import (
    auc,
    crossed_bootstrap,
    min_detectable_delta,
    permutation_p,
    smallest_p,
)


@pytest.mark.parametrize(
    ("k_a", "k_b", "floor"),
    [(3, 3, 0.1), (4, 4, 2 / 70), (5, 5, 2 / 252), (3, 4, 2 / 35), (1, 5, 1 / 3)],
)
def test_smallest_p_of_the_exact_test(k_a: int, k_b: int, floor: float) -> None:
    assert smallest_p(k_a, k_b) == pytest.approx(floor)


def test_the_most_extreme_split_reaches_the_floor_exactly() -> None:
    rng = np.random.default_rng(0)
    assert permutation_p(np.ones(3), np.zeros(3), rng) == pytest.approx(0.1)
    assert permutation_p(np.ones(5), np.zeros(5), rng) == pytest.approx(2 / 252)
    assert permutation_p(np.full(5, 0.5), np.full(5, 0.5), rng) == 1.0


def test_permutation_p_is_vectorised_over_designs() -> None:
    rng = np.random.default_rng(1)
    x, y = rng.random((7, 4)), rng.random((7, 4))
    batch = permutation_p(x, y, rng)
    assert batch.shape == (7,)
    assert batch == pytest.approx(
        [float(permutation_p(a, b, rng)) for a, b in zip(x, y, strict=True)]
    )


def test_auc_counts_ties_half() -> None:
    assert auc(np.array([1.0, 0.9]), np.array([0.1, 0.2])) == 1.0
    assert auc(np.array([0.5, 0.5]), np.array([0.5, 0.5])) == 0.5
    assert auc(np.array([0.0]), np.array([1.0, 0.5])) == 0.0


def test_crossed_bootstrap_resamples_the_matches_too() -> None:
    # identical seeds: a seeds-only bootstrap would give a zero-width interval, but which
    # matches happened to be contested is uncertain too
    kept_a = np.tile([1, 1, 1, 0, 1, 0, 1, 1], (5, 1)).astype(bool)
    kept_b = np.tile([0, 1, 0, 0, 0, 0, 1, 0], (5, 1)).astype(bool)
    low, high = crossed_bootstrap(kept_a, kept_b, np.random.default_rng(2))
    delta = kept_a.mean() - kept_b.mean()
    assert low < delta < high and high - low > 0.2


def test_crossed_bootstrap_resamples_the_seeds_too() -> None:
    kept_a = np.eye(4, dtype=bool)  # every seed keeps a different single match
    kept_b = np.zeros((4, 4), dtype=bool)
    low, high = crossed_bootstrap(kept_a, kept_b, np.random.default_rng(3))
    assert low < 0.25 < high
    assert crossed_bootstrap(kept_b, kept_b, np.random.default_rng(3)) == (0.0, 0.0)


def test_no_delta_is_detectable_where_the_test_cannot_reach_alpha() -> None:
    assert min_detectable_delta(11, 3, 3) is None
    assert min_detectable_delta(0, 5, 5) is None
    assert min_detectable_delta(11, 1, 10) is None


def test_min_detectable_delta_shrinks_with_matches_and_seeds() -> None:
    few, more, seeds = (
        min_detectable_delta(4, 5, 5),
        min_detectable_delta(16, 5, 5),
        min_detectable_delta(16, 10, 10),
    )
    assert few is not None and more is not None and seeds is not None
    assert 0 < seeds < more < few <= 1


def test_min_detectable_delta_is_close_to_the_normal_answer_at_many_seeds() -> None:
    n, k, seed_sd = 11, 20, 0.1
    variance = 1 / (4 * n) + seed_sd**2  # per-seed CA at agreement 1/2, plus seed spread
    normal = (norm.ppf(0.975) + norm.ppf(0.8)) * math.sqrt(2 * variance / k)
    assert min_detectable_delta(n, k, k, seed_sd=seed_sd) == pytest.approx(normal, abs=0.04)


def test_the_test_detects_the_min_detectable_delta_with_the_stated_power() -> None:
    """An independent simulation (other seed) of the same model reaches about 80% power."""
    n, k = 8, 5
    delta = min_detectable_delta(n, k, k)
    assert delta is not None
    rng = np.random.default_rng(99)
    sims = 2000

    def ca(p: float) -> np.ndarray:
        truth = np.clip(p + rng.normal(0, 0.1, (sims, k)), 0, 1)
        return rng.binomial(n, truth) / n

    p = permutation_p(ca(0.5 + delta / 2), ca(0.5 - delta / 2), rng, n_resamples=999)
    assert np.mean(p <= 0.05) == pytest.approx(0.8, abs=0.05)
