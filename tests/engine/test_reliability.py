"""Reliability from known-answer checks (MACE's competence, closed form) and pooling weighted
by it (issue 28 §2)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import beta

from engine.crowd_sim import CROWD, TASTES, member_checks, noise_free_tree, one_crowd
from engine.errors import InputError
from engine.pipeline import replay_with_teacher, run_tournament
from engine.pooling import pooled_advice, pooled_tree
from engine.reliability import Checks, competence, gold_interval
from engine.teachers import TEACHERS


@pytest.mark.parametrize(
    "checks",
    [Checks(), Checks(4, 4, 3, 3), Checks(2, 4, 1, 3), Checks(0, 4, 0, 3), Checks(30, 40, 9, 10)],
)
def test_competence_is_the_posterior_mean_of_truncated_theta(checks: Checks) -> None:
    """Against numerical integration of E[max(0, 2X - 1)], X ~ Beta(1 + k, 1 + n - k)."""
    a, b = 1 + checks.right, 1 + checks.asked - checks.right
    expected, _ = quad(lambda x: (2 * x - 1) * beta.pdf(x, a, b), 0.5, 1)
    assert competence(checks) == pytest.approx(expected, abs=1e-9)


def test_competence_orders_careful_above_clickers_and_grows_with_evidence() -> None:
    assert competence(Checks()) == pytest.approx(0.25)
    assert competence(Checks(4, 4, 0, 3)) < competence(Checks(4, 4, 3, 3))
    assert competence(Checks(40, 40, 30, 30)) > competence(Checks(4, 4, 3, 3)) > 0.75
    assert competence(Checks(20, 40, 15, 30)) < 0.1  # a clicker, however many checks
    assert 0.0 <= competence(Checks(0, 40, 0, 30)) < 1e-6


def test_gold_interval_is_clopper_pearson() -> None:
    assert gold_interval(Checks()) is None
    low, high = gold_interval(Checks(4, 4)) or (0, 0)
    assert high == 1.0 and low == pytest.approx(0.025 ** (1 / 4))  # exact: (alpha/2)^(1/n)


@pytest.mark.parametrize("bad", [(5, 4, 0, 0), (0, 0, -1, 3), (0, 0, 4, 3)])
def test_impossible_checks_are_refused(bad: tuple[int, int, int, int]) -> None:
    with pytest.raises(InputError, match="right <= asked"):
        Checks(*bad)


@pytest.fixture(scope="module")
def people() -> list:
    base = run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=4, teacher="standing")
    return [base, replay_with_teacher(base, "orthogonal"), replay_with_teacher(base, "random")]


def test_weights_decide_the_pool(people: list) -> None:
    qpos = np.stack([c.qpos for c in people[0].candidates])
    plain = pooled_advice(people)(qpos)
    assert np.allclose(pooled_advice(people, weights=[2, 2, 2])(qpos), plain)
    only_first = pooled_advice(people, weights=[1, 0, 0])(qpos)
    assert np.allclose(only_first, pooled_advice(people[:1] * 2)(qpos))
    assert pooled_tree(people, weights=[1, 0, 0]).results == people[0].results


@pytest.mark.parametrize("weights", [[1, 1], [1, -1, 1], [0, 0, 0]])
def test_bad_weights_are_refused(people: list, weights: list[float]) -> None:
    with pytest.raises(InputError, match="pool weights"):
        pooled_advice(people, weights=weights)


def test_the_simulated_checks_separate_careful_people_from_clickers() -> None:
    rng = np.random.default_rng(0)
    mean = {
        kind: np.mean([competence(member_checks(kind, rng)) for _ in range(300)])
        for kind in ("standing", "random", "always-left")
    }
    assert mean["standing"] > 0.6 > 0.2 > mean["random"] > mean["always-left"]
    assert "orthogonal" in TEACHERS


def test_one_simulated_crowd_reports_agreement_and_weight_shares() -> None:
    base = run_tournament(env_id="Humanoid-v5", n_candidates=8, p=0.9, seed=0, teacher="standing")
    truth = {taste: noise_free_tree(base, taste) for taste in TASTES}
    row = one_crowd(base, truth, np.random.default_rng(1))
    shares = [row[f"weight/{kind}"] for kind in CROWD]
    assert sum(shares) == pytest.approx(1.0)
    assert row["weight/always-left"] < 2 / 18 and row["weight/random"] < 3 / 18
    assert all(0 <= row[f"{m}/{t}"] <= 1 for m in ("plain", "weighted") for t in TASTES)
    assert truth["standing"].results != truth["orthogonal"].results
