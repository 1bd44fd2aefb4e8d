"""Validation round 2 (issue 40 §3), declared before any of its runs (docs/validation.md §6):
its seed ranges, arms per advice bracket, the rule that draws each bracket's unrelated
shuffled tree, and the ground truth's test.

Round 1 (:mod:`engine.validation.design`) stays as it was reported; every seed range here is
fresh. Several *advice brackets* replicate the verdict: each has its own candidates, its own
tree (the advice its advised arms train on) and its own shuffled arm; ``n1`` is shared and
judged on every bracket.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import permutation_test, spearmanr

from engine.advice import AdviceReward
from engine.errors import InputError
from engine.preference_tree import from_dendrogram
from engine.tournament import dendrogram
from engine.treefile import TreeDocument
from engine.verdict_bracket import alignment, tree_values
from engine.verdict_specificity import coin_results

#: Evaluation (training) seeds: ``n1`` trains seeds 100-109, every other arm 100-104, so the
#: product's verdict on each bracket pairs seed 100 + i with ``n1``'s seed 100 + i.
EVAL_SEED0 = 100
#: No-advice pilots (they sample the informative candidates only): seeds 2000, 2001.
PILOT_SEED0 = 2000
#: Advice bracket ``b`` draws its candidates and tree from seed 30000 + b.
BRACKET_SEED0 = 30_000
#: Bracket ``b``'s unrelated shuffled tree is drawn from seed 31000 + b.
SHUFFLE_SEED0 = 31_000
#: The ground truth U resets from these seeds (as in round 1), the behaviour judge from 0.
TRUTH_RESET_SEED0 = 10_000

#: |Spearman| of heights at most this, between a shuffled tree and the advice.
MAX_SHUFFLED_RHO = 0.2
#: An agent sitting at the shuffled tree's champion scores at most this |r| under the primary.
MAX_CHAMPION_R = 0.2
MAX_DRAWS = 10_000


@dataclass(frozen=True)
class ArmPlan:
    """One arm of round 2 on one env.

    Attributes:
        name: the arm (``n1``, ``p1-10``, ``n2-10``, ``bipars-em``, ``n3``, ...).
        seeds: evaluation seeds ``EVAL_SEED0 .. EVAL_SEED0 + seeds - 1``.
        brackets: the advice brackets it trains on (``()`` for ``n1``: judged on all).
        deciding: whether a criterion reads it (False: reported, never deciding).
    """

    name: str
    seeds: int
    brackets: tuple[int, ...]
    deciding: bool = True


#: Humanoid-v5 at 1M steps: 3 advice brackets, 65 runs and 2 pilots.
HUMANOID = (
    ArmPlan("n1", 10, ()),
    ArmPlan("p1-10", 5, (0, 1, 2)),
    ArmPlan("n2-10", 5, (0, 1, 2)),
    ArmPlan("bipars-em", 5, (0, 1)),
    ArmPlan("n3", 5, (0,)),
    ArmPlan("p1-10-noisy", 5, (0,), deciding=False),  # the teacher flips 20% of its matches
    ArmPlan("bipars-em-standing-shuffled", 5, (0,), deciding=False),  # §6.5
)
#: Hopper-v5 at 500k steps: the same shape without the reported arms, 50 runs and 2 pilots.
HOPPER = (
    ArmPlan("n1", 10, ()),
    ArmPlan("p1-10", 5, (0, 1, 2)),
    ArmPlan("n2-10", 5, (0, 1, 2)),
    ArmPlan("bipars-em", 5, (0, 1)),
)
DESIGNS = {"Humanoid-v5": (HUMANOID, 1_000_000), "Hopper-v5": (HOPPER, 500_000)}


def runs(design: tuple[ArmPlan, ...]) -> int:
    """Training runs of a design, pilots left out."""
    return sum(arm.seeds * max(1, len(arm.brackets)) for arm in design)


def semifinalists(doc: TreeDocument) -> set[int]:
    """The candidates that reached the last four (of a bracket without byes: the four
    highest heights)."""
    return _top(doc, 4)


def finalists(doc: TreeDocument) -> set[int]:
    """The two candidates that played the final."""
    return _top(doc, 2)


def _top(doc: TreeDocument, count: int) -> set[int]:
    order = sorted(doc.candidates, key=lambda c: -doc.tree.nodes[c.id].height)
    return {c.id for c in order[:count]}


def unrelated_tree(advice: TreeDocument, rng: np.random.Generator) -> TreeDocument:
    """A coin-flip tree over the advice's bracket that is unrelated to the advice, redrawn
    until all of §6.3's rules hold: |Spearman of heights| ≤ 0.2; neither of its finalists
    is among the advice's semi-finalists, nor the reverse; and an agent sitting at its
    champion scores |r| ≤ 0.2 with the advice under the primary (mean similarity).

    Raises:
        InputError: no draw of :data:`MAX_DRAWS` satisfies the rules.
    """
    own = tree_values(advice)
    kernel = AdviceReward.from_tree(advice)
    qpos = np.stack([c.qpos for c in advice.candidates])
    for _ in range(MAX_DRAWS):
        results = coin_results(advice.bracket, rng)
        doc = replace(
            advice,
            judge="shuffled",
            results=results,
            scores=None,
            ties=frozenset(),
            tree=from_dendrogram(dendrogram(advice.bracket, results), advice.r_b, advice.r_e),
        )
        values = tree_values(doc)
        sitting = kernel.similarity(qpos[int(np.argmax(values))][None])  # an agent there
        if (
            abs(spearmanr(values, own).statistic) <= MAX_SHUFFLED_RHO
            and not finalists(doc) & semifinalists(advice)
            and not finalists(advice) & semifinalists(doc)
            and abs(float(alignment(sitting, own)[0])) <= MAX_CHAMPION_R
        ):
            return doc
    raise InputError(f"no tree of {MAX_DRAWS} draws is unrelated to the advice")


def known_direction(arm_u: np.ndarray, baseline_u: np.ndarray, alpha: float = 0.05) -> str:
    """The ground truth of an arm (§6.3): ``follows`` when the one-sided exact permutation
    test of U, its seeds against the ``n1`` seeds (C(15, 5) = 3,003 arrangements at 5 and
    10), gives p < ``alpha``; ``rejects`` on the other side; ``unknown`` otherwise."""
    for direction, alternative in (("follows", "greater"), ("rejects", "less")):
        p = permutation_test(
            (arm_u, baseline_u),
            lambda x, y, axis=-1: np.mean(x, axis=axis) - np.mean(y, axis=axis),
            permutation_type="independent",
            alternative=alternative,
            vectorized=True,
            n_resamples=np.inf,
        ).pvalue
        if p < alpha:
            return direction
    return "unknown"
