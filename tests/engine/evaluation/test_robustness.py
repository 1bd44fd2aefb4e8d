"""Simulated evaluators that misbehave (issue 41 §4, "Robustness"): a side bias (65% left),
lapses (20% random), "can't tell" on close pairs and a taste unrelated to the advice raise no
false positives above the test's level; a noisy teacher sees round 1's known effect."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.evaluation.design import evaluator_pairs
from engine.evaluation.outcome import evaluate
from engine.evaluation.simulate import (
    RUN_SD,
    U_SCALE,
    CantTellWhenClose,
    Evaluator,
    Lapses,
    NoisyTeacher,
    SideBias,
    outcome_signs,
    simulate_answers,
    simulate_designs,
    synthetic_null_rate,
)
from engine.evaluation.stats import exact_p

MEASURES = Path(__file__).parents[3] / "docs/validation/humanoid-orthogonal/measures"
K5 = np.arange(10) < 5


@pytest.mark.parametrize(
    "evaluator",
    [SideBias(p_left=0.65), Lapses(rate=0.2), CantTellWhenClose(threshold=0.5)],
    ids=["side-bias-65", "lapses-20", "cant-tell-close"],
)
def test_no_false_positives_above_the_level(evaluator: Evaluator) -> None:
    rate = synthetic_null_rate(np.random.default_rng(43), n_designs=1000, evaluator=evaluator)
    assert rate <= 0.065, rate


def test_the_side_bias_shows_in_the_within_arm_left_rate() -> None:
    plans = [evaluator_pairs(10, 20, e, 3) for e in range(450)]  # 200 rounds of 45 pairs
    given = simulate_answers(np.zeros(10), plans, SideBias(0.65), np.random.default_rng(4))
    result = evaluate(given, K5, np.random.default_rng(5), "advisor", n_boot=200)
    assert (
        result.side_bias.rate == pytest.approx(0.65, abs=0.025) and result.side_bias.n == 200 * 20
    )
    assert result.between_arm.rate == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize(
    ("evaluator", "a_wins"),
    [(NoisyTeacher(scale=0.01), 1.0), (Lapses(0.2, NoisyTeacher(0.01)), 0.9)],
)
def test_lapses_answer_at_random(evaluator: Evaluator, a_wins: float) -> None:
    answers = evaluator.answer(np.ones(20000), np.zeros(20000), True, np.random.default_rng(0))
    assert answers.mean() == pytest.approx(a_wins, abs=0.01)


def test_cant_tell_on_close_pairs_only() -> None:
    close = CantTellWhenClose(threshold=0.5)
    answers = close.answer(
        np.array([0.2, 3.0]), np.array([0.0, 0.0]), False, np.random.default_rng(0)
    )
    assert answers[0] == 0.5 and answers[1] in (0.0, 1.0)
    assert float(close.answer(0.0, 0.1, True, np.random.default_rng(0))) == 0.5


def test_a_taste_unrelated_to_the_advice_does_not_say_more() -> None:
    """The orthogonal case: the advised runs follow the advice (their U is far higher), but
    the evaluator judges by its own taste, drawn independently of the arms. It says "more"
    no more often than its own exact test over its taste scores does, one-sided."""
    rng = np.random.default_rng(44)
    taste = rng.normal(0.0, RUN_SD, (1000, 10))  # independent of the arms' U
    batch = simulate_designs(taste, K5, 200, NoisyTeacher(), rng)
    more = outcome_signs(batch) == 1
    own_more = (exact_p(taste, K5) < 0.05) & (taste[:, K5].mean(1) > taste[:, ~K5].mean(1))
    assert more.mean() <= 0.035 and own_more.mean() <= 0.035  # one side of a 0.05 test
    assert (more & ~own_more).mean() <= 0.035


def test_a_noisy_teacher_sees_round_1s_known_effect() -> None:
    """p1-10 (known to follow, U 0.40-0.77) against n1 (U 0.20-0.38), judged by a teacher
    whose preferences are ``expit(ΔU / U_SCALE)``: 10 evaluators x 20 pairs say "more"."""
    truth = {
        arm: [json.loads((MEASURES / f"{arm}-{s}.json").read_text())["truth"] for s in range(5)]
        for arm in ("p1-10", "n1")
    }
    scores = np.array(truth["p1-10"] + truth["n1"])
    plans = [evaluator_pairs(10, 20, e, 41) for e in range(10)]
    for evaluator in (NoisyTeacher(U_SCALE), Lapses(0.2, NoisyTeacher(U_SCALE))):
        given = simulate_answers(scores, plans, evaluator, np.random.default_rng(1))
        result = evaluate(given, K5, np.random.default_rng(2), "advisor")
        assert result.outcome == "more" and result.p_value is not None
        assert result.p_value <= 4 / 252  # measured: 2/252 without lapses, 4/252 with
