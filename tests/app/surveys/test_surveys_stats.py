"""The survey statistics against values computed by hand: Clopper-Pearson bounds from their
definition (binomial tails at the bound equal 2.5%), and exact binomial p-values as sums of
binomial coefficients."""

from __future__ import annotations

from math import comb

import pytest

from app.surveys.stats import mean, median, paper_figures, proportion, versus_neutral


def _tail_at_least(k: int, n: int, p: float) -> float:
    return sum(comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1))


def _tail_at_most(k: int, n: int, p: float) -> float:
    return sum(comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(0, k + 1))


def test_all_twenty_of_twenty() -> None:
    """20/20: the lower bound solves p^20 = 0.025; p = 2 * 0.5^20 (two-sided)."""
    result = proportion(20, 20, chance=0.5)
    assert result.proportion == 1.0
    assert result.ci_low == pytest.approx(0.025 ** (1 / 20), rel=1e-9)  # 0.83157
    assert result.ci_low == pytest.approx(0.8315665, abs=1e-7)
    assert result.ci_high == 1.0
    assert result.p_value == pytest.approx(2 / 2**20, rel=1e-12)  # 1.9073e-06


def test_seventeen_of_twenty() -> None:
    """17/20: P(X >= 17) = (C(20,17) + C(20,18) + C(20,19) + C(20,20)) / 2^20 =
    1351 / 1048576, doubled for the two-sided test (the distribution is symmetric)."""
    result = proportion(17, 20, chance=0.5)
    assert comb(20, 17) + comb(20, 18) + comb(20, 19) + 1 == 1351
    assert result.p_value == pytest.approx(2 * 1351 / 2**20, rel=1e-12)  # 0.0025768
    assert result.ci_low == pytest.approx(0.6210732, abs=1e-6)
    assert result.ci_high == pytest.approx(0.9679291, abs=1e-6)
    # The bounds' definition: each one-sided tail at its bound is 2.5%.
    assert _tail_at_least(17, 20, result.ci_low) == pytest.approx(0.025, abs=1e-9)
    assert _tail_at_most(17, 20, result.ci_high) == pytest.approx(0.025, abs=1e-9)


def test_none_of_five_and_one_third_chance() -> None:
    """0/5: upper bound 1 - 0.025^(1/5); against chance 1/3 the two-sided p sums every
    outcome no likelier than 0 successes: P(0) = (2/3)^5 = 0.1317, plus P(4) = 10/243 and
    P(5) = 1/243 (P(3) = 40/243 = 0.165 is likelier)."""
    result = proportion(0, 5, chance=1 / 3)
    assert result.ci_low == 0.0
    assert result.ci_high == pytest.approx(1 - 0.025 ** (1 / 5), rel=1e-9)
    p0 = (2 / 3) ** 5  # 0.1317
    smaller = [comb(5, k) * (1 / 3) ** k * (2 / 3) ** (5 - k) for k in range(6)]
    expected = sum(pk for pk in smaller if pk <= p0 * (1 + 1e-7))
    assert expected == pytest.approx(32 / 243 + 10 / 243 + 1 / 243)  # 43/243 = 0.1770
    assert result.p_value == pytest.approx(expected, rel=1e-9)


def test_one_of_one_is_no_evidence() -> None:
    result = proportion(1, 1, chance=0.5)
    assert (result.ci_low, result.ci_high, result.p_value) == pytest.approx((0.025, 1.0, 1.0))


def test_no_answers_give_no_estimate() -> None:
    assert proportion(0, 0, chance=0.5) is None
    assert mean([]) is None and median([]) is None
    assert mean([4, 5]) == 4.5 and median([1000, 3000, 2000, 10_000]) == 2500.0


def test_the_papers_figures() -> None:
    q1, q2 = paper_figures()
    assert (q1["k"], q1["n"], q2["k"], q2["n"]) == (20, 20, 17, 20)
    assert q1["ci_low"] == pytest.approx(0.8316, abs=1e-4)
    assert (q2["ci_low"], q2["ci_high"]) == pytest.approx((0.6211, 0.9679), abs=1e-4)
    assert q2["proportion"] == 0.85


def test_likert_sign_test_against_the_neutral_value() -> None:
    """5, 4, 4, 3, 2 around 3: three above, one below, one at; p = P(|X - 2| >= 1), X ~ B(4, .5)."""
    result = versus_neutral([5, 4, 4, 3, 2], neutral=3)
    assert (result.above, result.below, result.at, result.median) == (3, 1, 1, 4)
    assert result.p_value == pytest.approx((comb(4, 0) + comb(4, 1) + comb(4, 3) + comb(4, 4)) / 16)
    assert versus_neutral([4, 4], neutral=4).p_value is None  # all at neutral: nothing to test
    assert versus_neutral([], neutral=4) is None
