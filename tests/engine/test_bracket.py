"""Braverman-Mossel seeding and bracket structure."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binomtest, chisquare

from engine.bracket import Bracket, bm_outcomes, bm_ranking, make_first_round, seed_positions
from engine.errors import InputError


@pytest.mark.parametrize(
    ("size", "expected"),
    [
        (2, [1, 2]),
        (4, [1, 4, 2, 3]),
        (8, [1, 8, 4, 5, 2, 7, 3, 6]),
    ],
)
def test_seed_positions_are_standard(size: int, expected: list[int]) -> None:
    assert seed_positions(size) == expected


def test_top_two_seeds_meet_only_in_final() -> None:
    order = seed_positions(64)
    assert order.index(1) < 32 <= order.index(2)


def test_p0_seeding_follows_env_reward() -> None:
    abilities = np.array([3.0, 9.0, 1.0, 7.0, 5.0, 2.0])
    ranked = bm_ranking(abilities, 0.0, np.random.default_rng(1))
    assert list(ranked) == list(np.argsort(-abilities))


def _seedings(p: float, draws: int = 4800) -> np.ndarray:
    """``draws`` BM rankings of 4 players of distinct ability, shape (draws, 4)."""
    rng = np.random.default_rng(123)
    return np.array([bm_ranking(np.arange(4.0), p, rng) for _ in range(draws)])


def _position_pvalues(ranked: np.ndarray) -> list[float]:
    """Chi-square p-value of "every player equally likely" at each seed position."""
    return [chisquare(np.bincount(ranked[:, k], minlength=4)).pvalue for k in range(4)]


def test_p1_seeding_is_uniform() -> None:
    ranked = _seedings(1.0)
    assert min(_position_pvalues(ranked)) > 0.01
    # and jointly: each of the 4! orders as likely as any other
    codes = ranked @ np.array([64, 16, 4, 1])
    counts = np.unique(codes, return_counts=True)[1]
    assert len(counts) == 24 and chisquare(counts).pvalue > 0.01


def test_the_uniformity_check_detects_partial_seeding() -> None:
    # p = 0.5: the stronger player wins 3/4 of the pairs, so seed 1 favours player 3
    assert max(_position_pvalues(_seedings(0.5, draws=1200))) < 1e-6


@pytest.mark.parametrize("p", [0.0, 0.5, 0.9])
def test_bm_outcome_is_correct_with_probability_one_minus_half_p(p: float) -> None:
    rng = np.random.default_rng(7)
    wins = sum(bool(bm_outcomes(np.array([1.0, 0.0]), p, rng)[0, 1]) for _ in range(3000))
    assert binomtest(wins, 3000, 1 - p / 2).pvalue > 0.01


def test_bm_outcomes_are_antisymmetric() -> None:
    beats = bm_outcomes(np.random.default_rng(0).normal(size=9), 0.9, np.random.default_rng(0))
    assert not beats.diagonal().any()
    off = ~np.eye(9, dtype=bool)
    assert (beats ^ beats.T)[off].all()


@pytest.mark.parametrize("n", [2, 3, 5, 6, 7, 8, 9, 16, 17, 33, 64])
def test_first_round_places_everyone_once_with_byes_to_top_seeds(n: int) -> None:
    abilities = np.arange(float(n))
    first = make_first_round(list(range(n)), abilities, 0.0, np.random.default_rng(0))
    size = 1 << (n - 1).bit_length()
    assert len(first) == size // 2
    players = [x for pair in first for x in pair if x is not None]
    assert sorted(players) == list(range(n))
    byes = [a for a, b in first if b is None]
    # p = 0: seeds follow ability, so the byes go to the strongest players.
    assert sorted(byes) == list(range(n - 1, n - 1 - (size - n), -1))[::-1]


@pytest.mark.parametrize("n", [2, 6, 16])
def test_bracket_counts(n: int) -> None:
    first = make_first_round(list(range(n)), np.arange(float(n)), 0.9, np.random.default_rng(0))
    bracket = Bracket(first)
    assert bracket.n_matches == n - 1
    assert bracket.n_rounds == max(1, (n - 1).bit_length())


def test_open_matches_wait_for_both_players() -> None:
    bracket = Bracket([(0, None), (1, 2)])
    assert [(m.round, m.a, m.b) for m in bracket.open_matches({})] == [(1, 1, 2)]
    assert [(m.round, m.a, m.b) for m in bracket.open_matches({(1, 1): 2})] == [(2, 0, 2)]
    assert bracket.is_complete({(1, 1): 2, (2, 0): 0})


@pytest.mark.parametrize(
    "bad", [[], [(0, 1), (2, 3), (4, 5)], [(0, 1), (1, 2)], [(None, 1), (2, 3)]]
)
def test_malformed_first_round_is_rejected(bad) -> None:
    with pytest.raises(InputError):
        Bracket(bad)


def test_fewer_than_two_players_is_rejected() -> None:
    with pytest.raises(InputError):
        make_first_round([0], np.zeros(1), 0.5, np.random.default_rng(0))


@pytest.mark.parametrize("p", [-0.1, 1.5])
def test_p_outside_unit_interval_is_rejected(p: float) -> None:
    with pytest.raises(InputError):
        bm_outcomes(np.zeros(3), p, np.random.default_rng(0))
