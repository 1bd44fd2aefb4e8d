"""The evaluation's statistic, exact p, interval and worded outcome (issue 41 §2), on answers
built by hand."""

from __future__ import annotations

import json
from itertools import combinations

import numpy as np
import pytest
from scipy.stats import permutation_test

from engine.evaluation.design import evaluator_pairs
from engine.evaluation.outcome import Outcome, decide, evaluate, guard_reason, sentence
from engine.evaluation.simulate import NoisyTeacher, simulate_answers
from engine.evaluation.stats import (
    Answers,
    between_arm_win_rate,
    exact_p,
    interval,
    permutation_p,
    side_bias,
    smallest_p,
    win_rates,
)

K5 = np.arange(10) < 5


def answers(rows: list[tuple[int, int, float]], left: bool = True, evaluator: int = 0) -> Answers:
    """``(a, b, winner_is_a)`` rows, ``a`` always shown on the left (``left``)."""
    a, b, w = (np.array(column) for column in zip(*rows, strict=True))
    chose_left = np.where(w == 1.0, left, not left) & (w != 0.5)
    return Answers(a, b, w, chose_left, np.full(len(rows), evaluator))


def round_robin_answers(n: int) -> Answers:
    """Every pair once, the lower index always winning: win rates ``(n-1-i)/(n-1)``."""
    return answers([(i, j, 1.0) for i, j in combinations(range(n), 2)])


def separated(k: int = 5, evaluators: int = 4) -> Answers:
    """Every advised run (the first k) beats every baseline run, within arms "can't tell";
    the same answers from each of ``evaluators``."""
    one = answers([(i, j, 1.0 if i < k <= j else 0.5) for i, j in combinations(range(2 * k), 2)])
    a, b, w, left = (
        np.tile(c, evaluators) for c in (one.a, one.b, one.winner_is_a, one.chose_left)
    )
    return Answers(a, b, w, left, np.repeat(np.arange(evaluators), one.n))


def test_win_rates_count_ties_half_and_every_opponent() -> None:
    found = win_rates(answers([(0, 1, 1.0), (0, 2, 0.5), (1, 2, 0.0), (2, 0, 1.0)]), 4)
    assert found[:3] == pytest.approx([1.5 / 3, 0 / 2, 2.5 / 3]) and np.isnan(found[3])


def test_p_on_four_runs_enumerated_by_hand() -> None:
    """Win rates 1, 2/3, 1/3, 0; runs 0, 1 advised: the statistic is 2/3. The 6 assignments
    give {0,1} 2/3, {0,2} 1/3, {0,3} 0, {1,2} 0, {1,3} -1/3, {2,3} -2/3: two reach |2/3|."""
    given = round_robin_answers(4)
    assert win_rates(given, 4) == pytest.approx([1, 2 / 3, 1 / 3, 0])
    assert permutation_p(given, np.array([True, True, False, False])) == pytest.approx(2 / 6)
    assert permutation_p(given, np.array([True, False, True, False])) == pytest.approx(4 / 6)


def test_exact_p_is_scipys_permutation_test_on_the_win_rates() -> None:
    rates = np.random.default_rng(0).random((5, 10))
    ours = exact_p(rates, K5)

    def stat(x: np.ndarray, y: np.ndarray, axis: int) -> np.ndarray:
        return np.mean(x, axis=axis) - np.mean(y, axis=axis)

    theirs = [permutation_test((r[K5], r[~K5]), stat, vectorized=True).pvalue for r in rates]
    assert ours == pytest.approx(theirs)


@pytest.mark.parametrize(("flip", "outcome"), [(False, "more"), (True, "less")])
def test_perfect_separation_at_k_5_gives_the_smallest_p(flip: bool, outcome: str) -> None:
    advised = ~K5 if flip else K5
    assert permutation_p(separated(), advised) == pytest.approx(2 / 252) == smallest_p(5, 5)
    result = evaluate(separated(), advised, np.random.default_rng(0), "advisor")
    assert result.outcome == outcome and result.p_value == pytest.approx(2 / 252)
    assert result.between_arm.rate == (0.0 if flip else 1.0) and result.between_arm.n == 100
    assert result.n_answers == 180 and result.n_evaluators == 4


def test_side_bias_and_between_arm_rates_by_hand() -> None:
    advised = np.array([True, True, False, False])
    given = answers([(0, 1, 1.0), (2, 3, 0.5), (0, 2, 0.0), (1, 3, 1.0), (2, 3, 0.0)])
    assert side_bias(given, advised).rate == pytest.approx((1 + 0.5 + 0) / 3)
    assert side_bias(given, advised).n == 3
    assert between_arm_win_rate(given, advised).rate == pytest.approx(0.5)
    assert side_bias(answers([(0, 2, 1.0)]), advised).rate is None


def test_the_interval_is_seeded_and_holds_the_statistic() -> None:
    given = simulate_answers(
        np.linspace(-1, 1, 10)[::-1],
        [evaluator_pairs(10, 20, e, 1) for e in range(6)],
        NoisyTeacher(),
        np.random.default_rng(2),
    )
    first = interval(given, K5, np.random.default_rng(3), n_boot=500)
    assert first == interval(given, K5, np.random.default_rng(3), n_boot=500)
    stat = np.nanmean(win_rates(given, 10)[K5]) - np.nanmean(win_rates(given, 10)[~K5])
    assert first[0] < stat < first[1]


def test_many_answers_about_equal_runs_say_no_different() -> None:
    plans = [evaluator_pairs(10, 20, e, 4) for e in range(60)]
    given = simulate_answers(np.zeros(10), plans, NoisyTeacher(), np.random.default_rng(5))
    result = evaluate(given, K5, np.random.default_rng(6), "others", n_boot=1000)
    assert result.outcome == "no_different", result
    assert result.interval is not None and -0.1 <= result.interval[0] <= result.interval[1] <= 0.1


@pytest.mark.parametrize(
    ("p", "stat", "ci", "outcome"),
    [
        (0.01, 0.2, (0.1, 0.3), "more"),
        (0.01, -0.2, (-0.3, -0.1), "less"),
        (0.01, 0.02, (-0.05, 0.05), "more"),  # p decides before the interval
        (0.30, 0.01, (-0.08, 0.09), "no_different"),
        (0.30, 0.05, (-0.08, 0.15), "cannot_tell"),
    ],
)
def test_the_outcome_rule(p: float, stat: float, ci: tuple[float, float], outcome: str) -> None:
    found, reason = decide(p, stat, ci, margin=0.1, alpha=0.05)
    assert found == outcome and (reason is None) == (outcome != "cannot_tell")


@pytest.mark.parametrize(
    ("n", "k_a", "k_b", "why"),
    [(0, 0, 0, "no answers"), (9, 1, 5, "fewer than 2 runs"), (9, 3, 2, "cannot go below")],
)
def test_rule_1_names_why_no_test_can_decide(n: int, k_a: int, k_b: int, why: str) -> None:
    assert why in str(guard_reason(n, k_a, k_b, alpha=0.05))
    assert guard_reason(9, 5, 5, alpha=0.05) is None


def test_too_few_runs_with_answers_cannot_tell() -> None:
    result = evaluate(answers([(0, 5, 1.0), (0, 6, 1.0)]), K5, np.random.default_rng(0), "advisor")
    assert result.outcome == "cannot_tell" and "fewer than 2 runs" in str(result.reason)
    assert result.sentence.endswith(f"{result.reason}.") and result.interval is None
    empty = Answers(*([],) * 5)  # type: ignore[arg-type]
    assert evaluate(empty, K5, np.random.default_rng(0), "advisor").reason == "no answers yet"


@pytest.mark.parametrize("outcome", ["more", "less", "no_different", "cannot_tell"])
def test_the_wording_follows_the_evaluator_kind(outcome: Outcome) -> None:
    advisor, others = sentence(outcome, "advisor", "why"), sentence(outcome, "others", "why")
    assert "what you asked for" in advisor and "your advice" in advisor
    assert "the instruction" in others and "you" not in others
    word = {"more": "does more", "less": "does less", "no_different": "no different"}
    assert word.get(outcome, "Cannot tell") in advisor


def test_the_result_goes_to_json() -> None:
    result = evaluate(separated(), K5, np.random.default_rng(0), "others")
    out = json.loads(json.dumps(result.to_json()))
    assert out["outcome"] == "more" and out["side_bias"] == {"rate": 0.5, "n": 80}
    assert len(out["win_rates"]) == 10 and len(out["interval"]) == 2


@pytest.mark.parametrize(
    "bad",
    [
        dict(a=[0], b=[0], winner_is_a=[1.0], chose_left=[True], evaluator=[0]),
        dict(a=[0], b=[1], winner_is_a=[0.7], chose_left=[True], evaluator=[0]),
        dict(a=[0, 1], b=[1], winner_is_a=[1.0], chose_left=[True], evaluator=[0]),
    ],
)
def test_malformed_answers_are_refused(bad: dict[str, list[float]]) -> None:
    with pytest.raises(ValueError):
        Answers(**bad)  # type: ignore[arg-type]


def test_an_answer_about_a_run_outside_the_arms_is_refused() -> None:
    with pytest.raises(ValueError, match="outside"):
        evaluate(answers([(0, 12, 1.0)]), K5, np.random.default_rng(0), "advisor")
