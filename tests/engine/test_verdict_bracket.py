"""The whole-bracket verdict (issue 40 §1) on synthetic agents whose answer is known: per-
candidate scores computed from visited states over a real Humanoid-v5 bracket (validation
round 1's bracket 0), as the behaviour judge computes them (engine/validation/synthetic.py)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.errors import InputError
from engine.treefile import load_tree
from engine.validation.synthetic import SyntheticAgents, SyntheticBracket
from engine.verdict_bracket import (
    AlignmentOptions,
    alignment,
    alignment_verdict,
    tree_values,
)
from engine.verdict_power import permutation_p
from engine.verdict_specificity import random_tree_values, specificity
from tests.support.candidates import r_judged_doc

ROUND1 = Path(__file__).parents[2] / "docs/validation/humanoid-orthogonal"
FAST = AlignmentOptions(n_boot=200)  # the interval never decides: the simulations skip most
NULL_DESIGNS = 1000


@pytest.fixture(scope="module")
def bracket() -> SyntheticBracket:
    return SyntheticBracket(load_tree(ROUND1 / "brackets/bracket_0.json"))


def test_alignment_is_pearson_and_zero_without_a_preference() -> None:
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(3, 16)), rng.normal(size=16)
    expected = [np.corrcoef(row, y)[0, 1] for row in x]
    np.testing.assert_allclose(alignment(x, y), expected, rtol=1e-12)
    assert alignment(np.full((2, 16), 0.3), y).tolist() == [0.0, 0.0]
    assert alignment(x, np.ones(16)).tolist() == [0.0, 0.0, 0.0]


def test_tree_values_read_the_tree_never_the_judges_scores() -> None:
    doc = r_judged_doc()
    assert doc.scores is not None  # the teacher's hidden scores are in the document
    heights = np.array([doc.tree.nodes[c.id].height for c in doc.candidates])
    np.testing.assert_allclose(tree_values(doc), doc.r_e * heights - doc.r_b)


def test_the_null_fires_at_the_tests_level(bracket: SyntheticBracket) -> None:
    """1,000 designs of 5 seeds against 5, no arm following the tree: "used" or "went
    against" in 5% ± 1.5% of them."""
    rng = np.random.default_rng(40)
    calls = [_outcome(bracket, 0.0, 0.0, 5, rng) for _ in range(NULL_DESIGNS)]
    fired = np.mean([c in ("used", "against") for c in calls])
    assert 0.035 <= fired <= 0.065, fired
    assert set(calls) <= {"used", "against", "no-different"}


@pytest.mark.parametrize(
    ("shift", "seeds", "expected"),
    # a tree has 8 leaves and 1 champion: turning away from it moves r less than following it
    [(1.0, 5, "used"), (-2.0, 10, "against")],
)
def test_agents_shifted_toward_or_away_from_the_tree(
    bracket: SyntheticBracket, shift: float, seeds: int, expected: str
) -> None:
    rng = np.random.default_rng(41)
    calls = [_outcome(bracket, shift, 0.0, seeds, rng) for _ in range(60)]
    assert np.mean([c == expected for c in calls]) >= 0.8
    assert not {"used", "against"} - {expected} & set(calls)  # never the other way


def _outcome(
    bracket: SyntheticBracket, shift: float, base: float, k: int, rng: np.random.Generator
) -> str | None:
    advised = bracket.draw(SyntheticAgents(shift), k, rng).similarity
    baseline = bracket.draw(SyntheticAgents(base), k, rng).similarity
    return alignment_verdict(bracket.values, advised, baseline, rng, FAST).outcome


@pytest.mark.parametrize(
    ("candidates", "seeds", "reason"),
    [(4, 5, "only 4 candidates in the bracket, at least 8 needed"), (16, 2, "at least 4 per arm")],
)
def test_too_small_a_design_cannot_tell(candidates: int, seeds: int, reason: str) -> None:
    doc = r_judged_doc(candidates)
    values = tree_values(doc)
    rng = np.random.default_rng(0)
    follows = values + rng.normal(0, 0.1, (seeds, candidates))
    v = alignment_verdict(values, follows, rng.normal(size=(seeds, candidates)), rng, FAST)
    assert v.outcome == "cannot-tell" and reason in (v.reason or "")
    assert reason in v.text


def test_constant_scores_cannot_tell() -> None:
    values = tree_values(r_judged_doc())
    flat = np.full((5, 16), 0.5)
    v = alignment_verdict(values, flat, flat, np.random.default_rng(0), FAST)
    assert v.outcome == "cannot-tell"
    assert v.reason == "the judge scores every candidate alike on every run"


def test_interim_and_diagnostic_looks_carry_no_outcome_word(bracket: SyntheticBracket) -> None:
    rng = np.random.default_rng(42)
    advised = bracket.draw(SyntheticAgents(2.0), 5, rng).similarity
    baseline = bracket.draw(SyntheticAgents(0.0), 5, rng).similarity
    primary = alignment_verdict(bracket.values, advised, baseline, rng, FAST)
    assert primary.outcome == "used"
    for stage in ("interim", "diagnostic"):
        look = alignment_verdict(bracket.values, advised, baseline, rng, FAST, stage=stage)
        assert look.outcome is None and look.delta == primary.delta
        assert "used" not in look.text and f"{stage}, no verdict" in look.text
    assert json.loads(json.dumps(primary.to_json()))["outcome"] == "used"


def test_bad_shapes_are_refused() -> None:
    with pytest.raises(InputError, match="shape"):
        alignment_verdict(
            np.arange(16.0), np.zeros((5, 15)), np.zeros((5, 16)), np.random.default_rng(0)
        )
    with pytest.raises(InputError, match="finite"):
        alignment_verdict(
            np.arange(16.0), np.full((5, 16), np.nan), np.zeros((5, 16)), np.random.default_rng(0)
        )


def test_power_rises_with_seeds(bracket: SyntheticBracket) -> None:
    """The power table of §6.2 at k = 3, 5, 8, 10 seeds per arm: none at 3 (the exact test's
    floor, and the "cannot tell" rule), then rising with k."""
    powers = []
    for k in (3, 5, 8, 10):
        rng = np.random.default_rng(43)
        calls = [_outcome(bracket, 0.5, 0.0, k, rng) for _ in range(60)]
        powers.append(np.mean([c == "used" for c in calls]))
    assert powers[0] == 0.0
    assert powers[1] < powers[2] < powers[3], powers


def test_specificity_ranks_the_persons_tree_among_random_trees(bracket: SyntheticBracket) -> None:
    doc = load_tree(ROUND1 / "brackets/bracket_0.json")
    rng = np.random.default_rng(44)
    follows = bracket.draw(SyntheticAgents(2.0), 5, rng).similarity
    ignores = bracket.draw(SyntheticAgents(0.0), 200, rng).similarity
    assert (specificity(follows, doc, rng, trees=300) > 0.75).all()
    null = specificity(ignores, doc, rng, trees=300)
    assert 0.4 < null.mean() < 0.6  # an agent that ignores the tree: uniform, mean 1/2


def test_random_trees_share_the_bracket() -> None:
    doc = r_judged_doc()
    trees = random_tree_values(doc, 50, np.random.default_rng(0))
    own = tree_values(doc)
    # same bracket, so the same multiset of rounds won: 8 first-round losers, ..., 1 champion
    assert all(sorted(row) == sorted(own) for row in trees)
    assert len({tuple(row) for row in trees}) > 40


def test_round_1_behaviour_measures_reproduce_the_hypothesis() -> None:
    """Issue 40's reading of round 1 (found after looking: a hypothesis, not evidence):
    Pearson r of `behaviour` with T_r on bracket 0 puts every p1-10 and bipars-em seed above
    every n1, n2-1 and n2-10 seed, and says "used" for both advised arms at p = 2/252."""
    values = tree_values(load_tree(ROUND1 / "brackets/bracket_0.json"))
    r = {
        arm: alignment(_scores(arm), values)
        for arm in ("n1", "n2-1", "n2-10", "p1-10", "bipars-em")
    }
    assert min(min(r["p1-10"]), min(r["bipars-em"])) > max(
        max(r["n1"]), max(r["n2-1"]), max(r["n2-10"])
    )
    p = permutation_p(r["p1-10"], r["n1"], np.random.default_rng(0))
    assert float(p) == pytest.approx(2 / 252)


def _scores(arm: str) -> np.ndarray:
    return np.array(
        [
            json.loads((ROUND1 / f"measures/{arm}-{s}.json").read_text())["scores"]["behaviour"][0]
            for s in range(5)
        ]
    )
