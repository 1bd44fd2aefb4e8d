"""Disagreement pairs: where the advice and a no-advice baseline disagree most clearly."""

from __future__ import annotations

import numpy as np
import pytest

from engine.disagreement import MAX_PAIRS, disagreement_pairs
from engine.errors import InputError
from engine.verdict import VerdictOptions, split_matches

#: Advice heights and a baseline that ranks the candidates the other way round.
ADVICE = np.array([3.0, 2.0, 1.0, 0.0])
REVERSED = np.array([0.0, 10.0, 20.0, 30.0])


def test_the_clearest_disagreement_comes_first() -> None:
    pairs = disagreement_pairs(ADVICE, REVERSED, k=3)
    assert pairs[0] == (0, 3)  # advice's best against its worst: the baseline's best
    assert set(pairs[1:]) == {(0, 2), (1, 3)}  # both lead by 2/3 of either spread


def test_an_agreeing_baseline_gives_no_pair() -> None:
    assert disagreement_pairs(ADVICE, ADVICE * 10, k=MAX_PAIRS) == []


@pytest.mark.parametrize("k", [0, 1, 2, 6])
def test_at_most_k_pairs_each_a_disagreement(k: int) -> None:
    rng = np.random.default_rng(k)
    advice, baseline = rng.integers(0, 4, 8).astype(float), rng.normal(size=8)
    pairs = disagreement_pairs(advice, baseline, k=k)
    assert len(pairs) <= k
    for a, b in pairs:
        assert advice[a] > advice[b] and baseline[b] > baseline[a]


def test_played_pairs_are_left_out_in_either_order() -> None:
    pairs = disagreement_pairs(ADVICE, REVERSED, k=MAX_PAIRS, played=[(3, 0), (1, 3)])
    assert (0, 3) not in pairs and (1, 3) not in pairs and len(pairs) == 4


def test_a_baseline_gap_below_the_margin_is_no_disagreement() -> None:
    baseline = np.array([0.0, 0.01, 0.0, 1.0])  # 1 over 0 by 1% of the spread
    pairs = disagreement_pairs(ADVICE, baseline, k=MAX_PAIRS, margin_baseline=0.05)
    assert (0, 1) not in pairs and (0, 3) in pairs


def test_every_pair_is_contested_for_the_verdict_when_the_participant_follows_the_advice() -> None:
    """The verdict's own split, with the same margins, counts every answered pair."""
    pairs = disagreement_pairs(ADVICE, REVERSED, k=MAX_PAIRS)
    classes = split_matches(ADVICE, REVERSED, tuple((a, b, a) for a, b in pairs), VerdictOptions())
    assert len(classes.contested) == len(pairs) == 6


@pytest.mark.parametrize("k", [-1, MAX_PAIRS + 1])
def test_k_out_of_range_is_refused(k: int) -> None:
    with pytest.raises(InputError, match="disagreement pairs"):
        disagreement_pairs(ADVICE, REVERSED, k=k)


def test_scores_of_different_lengths_are_refused() -> None:
    with pytest.raises(InputError, match="one length"):
        disagreement_pairs(ADVICE, REVERSED[:3], k=1)
