"""Position bias, pairwise agreement and Krippendorff's alpha against hand-computed values."""

from __future__ import annotations

import pytest

from engine.agreement import (
    alpha_nominal,
    mean_agreement,
    pair_key,
    pairwise_agreement,
    shared_units,
    side_bias,
)

#: Three labellers; (0, 1) and (2, 3) decided by all, (0, 2) by the first two.
CHOICES = {
    1: {(0, 1): 0, (2, 3): 2, (0, 2): 0},
    2: {(0, 1): 0, (2, 3): 3, (0, 2): 0},
    3: {(0, 1): 1, (2, 3): 3},
}


def test_side_bias_is_an_exact_two_sided_binomial_test() -> None:
    # P(X >= 7 | n = 10, 1/2) = (120 + 45 + 10 + 1) / 1024; two-sided doubles it.
    assert side_bias(left=7, labels=10).p_value == pytest.approx(352 / 1024)
    assert side_bias(left=7, labels=10).left_share == 0.7
    assert side_bias(left=5, labels=10).p_value == pytest.approx(1.0)
    assert side_bias(left=0, labels=0).p_value is None


def test_pairwise_agreement_on_shared_pairs() -> None:
    pairs = pairwise_agreement(CHOICES)
    assert [(p.a, p.b, p.shared, p.agreement) for p in pairs] == [
        (1, 2, 3, pytest.approx(2 / 3)),
        (1, 3, 2, 0.0),
        (2, 3, 2, 0.5),
    ]
    assert mean_agreement(pairs) == pytest.approx((2 / 3 + 0 + 0.5) / 3)
    assert shared_units(CHOICES) == [(0, 1), (0, 2), (2, 3)]
    assert pairwise_agreement({1: {(0, 1): 0}, 2: {(2, 3): 2}})[0].agreement is None


def test_krippendorff_alpha_nominal_by_hand() -> None:
    # Values (1: the higher id won): (0,1) -> [0, 0, 1], (2,3) -> [0, 1, 1], (0,2) -> [0, 0].
    # Coincidences: o00 = 1 + 0 + 2 = 3, o01 = o10 = 1 + 1 = 2, o11 = 1; n0 = 5, n1 = 3,
    # n = 8. Do = 4/8, De = 2 * 5 * 3 / (8 * 7) = 30/56: alpha = 1 - (1/2) / (30/56) = 1/15.
    assert alpha_nominal(CHOICES) == pytest.approx(1 / 15)


def test_alpha_is_undefined_without_shared_pairs_or_variation() -> None:
    assert alpha_nominal({1: {(0, 1): 0}, 2: {(2, 3): 2}}) is None
    assert alpha_nominal({1: {(0, 1): 0}, 2: {(0, 1): 0}}) is None
    assert pair_key(5, 2) == (2, 5)


def test_alpha_is_undefined_when_only_unpaired_values_vary() -> None:
    # labeller 3 alone decides (2, 3) the other way: no shared pair varies
    assert alpha_nominal({1: {(0, 1): 0}, 2: {(0, 1): 0}, 3: {(2, 3): 3}}) is None
