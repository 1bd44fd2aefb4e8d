"""The evaluation's pairs (issue 41 §1, "Pairs over all runs"): every pair of the 2k runs,
within-arm pairs included, balanced so each run appears equally often, sides seeded."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from scipy.stats import binomtest

from engine.evaluation.design import evaluator_pairs, pair_sequence, round_robin


@pytest.mark.parametrize("n_runs", [2, 3, 4, 5, 10, 11])
def test_a_round_robin_holds_every_pair_once_in_disjoint_matchings(n_runs: int) -> None:
    schedule = round_robin(n_runs)
    pairs = {tuple(p) for p in schedule.reshape(-1, 2).tolist()}
    assert len(pairs) == schedule.shape[0] * schedule.shape[1] == math.comb(n_runs, 2)
    assert all(len(set(m.ravel().tolist())) == m.size for m in schedule)


@pytest.mark.parametrize("n_runs", [3, 10, 11])
def test_every_round_of_the_sequence_shows_every_pair_once(n_runs: int) -> None:
    per_round = math.comb(n_runs, 2)
    sequence = pair_sequence(n_runs, 0, 12 * per_round, rng_seed=3)  # crosses a block
    for r in range(12):
        round_pairs = Counter(map(tuple, sequence[r * per_round : (r + 1) * per_round].tolist()))
        assert len(round_pairs) == per_round and set(round_pairs.values()) == {1}
    assert (sequence[:, 0] < sequence[:, 1]).all()


def test_within_arm_pairs_are_20_of_45_at_k_5() -> None:
    advised = np.arange(10) < 5
    plan = evaluator_pairs(10, 45 * 8, evaluator=0, rng_seed=11)
    within = advised[plan.a] == advised[plan.b]
    assert within.reshape(8, 45).sum(axis=1).tolist() == [20] * 8


@pytest.mark.parametrize("evaluator", [0, 1, 2, 7])
def test_each_evaluator_sees_each_of_10_runs_4_times_in_20_pairs(evaluator: int) -> None:
    plan = evaluator_pairs(10, 20, evaluator, rng_seed=5)
    assert np.bincount(np.concatenate([plan.a, plan.b]), minlength=10).tolist() == [4] * 10


def test_over_evaluators_every_pair_is_shown_equally_often() -> None:
    plans = [evaluator_pairs(10, 20, e, rng_seed=9) for e in range(9)]  # 180 = 4 rounds
    a, b = np.concatenate([p.a for p in plans]), np.concatenate([p.b for p in plans])
    counts = Counter(zip(a.tolist(), b.tolist(), strict=True))
    assert len(counts) == 45 and set(counts.values()) == {4}


def test_an_evaluator_gets_the_next_stretch_of_one_sequence() -> None:
    plan = evaluator_pairs(10, 20, evaluator=3, rng_seed=2)
    stretch = pair_sequence(10, 60, 80, rng_seed=2)
    assert (plan.a == stretch[:, 0]).all() and (plan.b == stretch[:, 1]).all()


def test_the_plan_is_deterministic_given_its_arguments() -> None:
    first, again = evaluator_pairs(10, 20, 4, 123), evaluator_pairs(10, 20, 4, 123)
    for field in ("a", "b", "a_left"):
        assert (getattr(first, field) == getattr(again, field)).all()
    other_seed, other_evaluator = evaluator_pairs(10, 20, 4, 124), evaluator_pairs(10, 20, 5, 123)
    assert not (first.a == other_seed.a).all() or not (first.b == other_seed.b).all()
    assert not (first.a_left == other_evaluator.a_left).all()


def test_sides_are_a_fair_coin() -> None:
    lefts = np.concatenate([evaluator_pairs(10, 20, e, 8).a_left for e in range(200)])
    assert binomtest(int(lefts.sum()), lefts.size).pvalue > 0.01
    assert abs(lefts.mean() - 0.5) < 0.03


@pytest.mark.parametrize(
    ("n_runs", "n_pairs", "evaluator", "message"),
    [(1, 20, 0, "at least 2 runs"), (10, 0, 0, "at least 1 pair"), (10, 20, -1, ">= 0")],
)
def test_bad_arguments_are_refused(n_runs: int, n_pairs: int, evaluator: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        evaluator_pairs(n_runs, n_pairs, evaluator, rng_seed=0)
