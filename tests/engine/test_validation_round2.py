"""Validation round 2's declared design (docs/validation.md §6.3): the unrelated shuffled
trees' rules, the ground truth's test and the budget."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.stats import spearmanr

from engine.advice import AdviceReward
from engine.treefile import load_tree
from engine.validation.design import AdviceKind
from engine.validation.round2 import (
    HOPPER,
    HUMANOID,
    MAX_CHAMPION_R,
    MAX_SHUFFLED_RHO,
    SHUFFLE_SEED0,
    finalists,
    known_direction,
    runs,
    semifinalists,
    unrelated_tree,
)
from engine.validation.round2_runs import Round2Plan, _control, arm_of, tasks
from engine.verdict_bracket import alignment, tree_values

BRACKETS = Path(__file__).parents[2] / "docs/validation/humanoid-orthogonal/brackets"


@pytest.mark.parametrize("b", [0, 1, 2])
def test_shuffled_trees_are_unrelated_to_the_advice(b: int) -> None:
    advice = load_tree(BRACKETS / f"bracket_{b}.json")
    shuffled = unrelated_tree(advice, np.random.default_rng(SHUFFLE_SEED0 + b))
    own, other = tree_values(advice), tree_values(shuffled)
    assert abs(spearmanr(own, other).statistic) <= MAX_SHUFFLED_RHO
    assert not finalists(shuffled) & semifinalists(advice)
    assert not finalists(advice) & semifinalists(shuffled)
    champion = advice.candidates[int(np.argmax(other))].qpos[None]
    sitting = AdviceReward.from_tree(advice).similarity(champion)
    assert abs(alignment(sitting, own)[0]) <= MAX_CHAMPION_R
    # the same bracket and candidates, a tree of its own with no hidden scores
    assert shuffled.first_round == advice.first_round and shuffled.scores is None
    assert shuffled.judge == "shuffled" and sorted(other) == sorted(own)
    again = unrelated_tree(advice, np.random.default_rng(SHUFFLE_SEED0 + b))
    assert again.results == shuffled.results  # seeded: recorded and redrawn alike


def test_the_ground_truth_is_the_exact_one_sided_test_against_ten_seeds() -> None:
    n1 = np.linspace(0.2, 0.3, 10)
    assert known_direction(np.full(5, 0.5) + np.arange(5) / 100, n1) == "follows"
    assert known_direction(np.full(5, 0.1) + np.arange(5) / 100, n1) == "rejects"
    assert known_direction(n1[::2], n1) == "unknown"
    # 5 above all 10: p = 1/3003; 4 above and the fifth in the middle still follows
    assert known_direction(np.array([0.25, 0.5, 0.5, 0.5, 0.5]), n1) == "follows"


def test_the_budget_is_the_declared_one() -> None:
    assert runs(HUMANOID) == 65 and runs(HOPPER) == 50


def test_every_declared_run_is_a_task_once_pilots_and_baseline_first() -> None:
    plan = Round2Plan(env_id="Humanoid-v5", timesteps=1_000_000)
    found = tasks(plan)
    assert len(found) == runs(HUMANOID) + 2 and len(set(found)) == len(found)
    assert found[:2] == [("pilot", 2000), ("pilot", 2001)]
    assert found[2:12] == [("n1", 100 + k) for k in range(10)]
    assert ("bipars-em.b1", 104) in found and ("bipars-em.b2", 100) not in found
    assert ("n3.b0", 100) in found and ("n3.b1", 100) not in found
    assert plan.brackets == 3
    arm, bracket = arm_of("n2-10.b2")
    assert (arm.advice, arm.scale, bracket) == (AdviceKind.SHUFFLED, 10.0, 2)
    assert arm_of("n1") == (arm_of("n1")[0], None)


@pytest.mark.parametrize("kind", [AdviceKind.SHUFFLED, AdviceKind.INVERTED, AdviceKind.NOISY])
def test_each_control_is_a_tree_over_the_advice_bracket_without_scores(kind: AdviceKind) -> None:
    teacher_tree = load_tree(BRACKETS / "bracket_0.json")
    plan = Round2Plan(env_id="Humanoid-v5", timesteps=1_000_000)
    control = _control(kind, teacher_tree, plan, 0)
    assert control.scores is None and control.first_round == teacher_tree.first_round
    assert control.results != teacher_tree.results
    own, other = tree_values(teacher_tree), tree_values(control)
    if kind is AdviceKind.INVERTED:  # the advice's champion is the inverted tree's first loser
        assert other[int(np.argmax(own))] == other.min()
    if kind is AdviceKind.NOISY:  # 20% of the matches flipped: still close to the advice
        assert spearmanr(own, other).statistic > 0.3
