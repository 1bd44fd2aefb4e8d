"""The evaluators and answers a design needs (issue 41 §2 "Shown", §4 "Power"), by simulation
of the exact design and test; small numbers of simulations keep these fast."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import expit, logit

from engine.evaluation.power import answers_needed, arm_effect, power_table
from engine.evaluation.simulate import RUN_SD


def test_the_arm_effect_gives_the_declared_between_arm_win_rate() -> None:
    assert arm_effect(0.5, RUN_SD) == pytest.approx(0.0, abs=1e-9)
    assert arm_effect(0.65, 0.0) == pytest.approx(logit(0.65))
    delta = arm_effect(0.65, RUN_SD)
    e = np.random.default_rng(0).normal(0.0, np.sqrt(2) * RUN_SD, 400_000)
    assert expit(delta + e).mean() == pytest.approx(0.65, abs=0.002)
    assert delta > logit(0.65)  # run effects flatten the curve


@pytest.mark.parametrize("win_rate", [0.0, 1.0, 1.2])
def test_a_win_rate_outside_0_1_is_refused(win_rate: float) -> None:
    with pytest.raises(ValueError, match="win_rate"):
        arm_effect(win_rate, RUN_SD)


def test_power_grows_with_evaluators_and_holds_the_level_without_an_effect() -> None:
    table = power_table(0.85, 5, RUN_SD, 20, (1, 5, 20), np.random.default_rng(0), n_sims=300)
    assert table.answers.tolist() == [20, 100, 400]
    assert np.all(np.diff(table.power) >= 0) and table.power[-1] > 0.8
    null = power_table(0.5, 5, RUN_SD, 20, (10,), np.random.default_rng(0), n_sims=300)
    assert null.power[0] <= 0.05


def test_only_the_total_of_answers_counts() -> None:
    """E evaluators of m pairs answer the first E * m pairs of one sequence."""
    twenty = power_table(0.8, 5, RUN_SD, 20, (5,), np.random.default_rng(1), n_sims=200)
    ten = power_table(0.8, 5, RUN_SD, 10, (10,), np.random.default_rng(1), n_sims=200)
    assert twenty.power.tolist() == ten.power.tolist()


def test_with_round_1s_run_spread_065_is_out_of_reach_at_k_5() -> None:
    needed = answers_needed(0.65, 5, RUN_SD, 20, np.random.default_rng(0), n_sims=300)
    assert needed.evaluators is None and needed.answers is None
    assert needed.power < 0.5  # measured: about 0.31 with 100 evaluators


@pytest.mark.parametrize(
    ("win_rate", "run_sd", "low", "high"),
    [(0.85, RUN_SD, 2, 8), (0.65, 0.0, 8, 20)],  # measured (1,000 designs): 4 and 12
)
def test_answers_needed(win_rate: float, run_sd: float, low: int, high: int) -> None:
    needed = answers_needed(win_rate, 5, run_sd, 20, np.random.default_rng(0), n_sims=300)
    assert needed.evaluators is not None and low <= needed.evaluators <= high
    assert needed.answers == needed.evaluators * 20 and needed.power >= 0.8
