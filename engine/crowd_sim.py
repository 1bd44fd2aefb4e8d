"""Simulated crowds whose truth is known: people of two tastes and two kinds of clicker, each
labelling one bracket and answering known-answer checks (issue 28 §2;
``benchmarks/crowd_reliability.py`` runs them, docs/method.md §2.13 reports them).

Careful people are noisy teachers (taste noise :data:`NOISE`); random and always-left
clickers decide the bracket by a coin (sides are drawn per match, so always-left is a coin
over postures too). Gold items: a careful person errs with probability :data:`GOLD_ERROR`, a
clicker is right half the time. Consistency pairs (a match again, sides swapped): a careful
person agrees unless exactly one decision flips, a random clicker half the time, an
always-left clicker never.
"""

from __future__ import annotations

import numpy as np

from engine.conformance import compare
from engine.envs import env_model
from engine.pooling import pooled_tree
from engine.reliability import Checks, competence
from engine.teachers import make_teacher
from engine.treefile import TreeDocument, replay

TASTES = ("standing", "orthogonal")
CROWD = {"standing": 7, "orthogonal": 6, "random": 3, "always-left": 2}
NOISE, GOLD_ERROR, GOLD, CONSISTENCY = 0.1, 0.05, 4, 3


def member_tree(base: TreeDocument, kind: str, rng: np.random.Generator) -> TreeDocument:
    """One participant's tree: a noisy teacher, or a coin for either clicker."""
    teacher, noise = (kind, NOISE) if kind in TASTES else ("random", 0.0)
    judge, _ = make_teacher(teacher, base.candidates, env_model(base.env_id), noise=noise, rng=rng)
    return replay(base, judge, kind)


def noise_free_tree(base: TreeDocument, taste: str) -> TreeDocument:
    """What a taste's teacher decides without noise: the tree pooling should recover."""
    judge, _ = make_teacher(
        taste, base.candidates, env_model(base.env_id), rng=np.random.default_rng(0)
    )
    return replay(base, judge, taste)


def member_checks(kind: str, rng: np.random.Generator) -> Checks:
    """The participant's gold items and consistency pairs, drawn as the module says."""
    careful = kind in TASTES
    gold = rng.random(GOLD) < (1 - GOLD_ERROR if careful else 0.5)
    if careful:  # agree unless exactly one of the two decisions flips
        agree = (rng.random(CONSISTENCY) < NOISE) == (rng.random(CONSISTENCY) < NOISE)
    else:
        agree = rng.random(CONSISTENCY) < (0.5 if kind == "random" else 0.0)
    return Checks(int(gold.sum()), GOLD, int(agree.sum()), CONSISTENCY)


def one_crowd(
    base: TreeDocument, truth: dict[str, TreeDocument], rng: np.random.Generator
) -> dict[str, float]:
    """Agreement of each pooling with each taste's truth, and each group's weight share."""
    kinds = [kind for kind, n in CROWD.items() for _ in range(n)]
    trees = [member_tree(base, kind, rng) for kind in kinds]
    weights = np.array([competence(member_checks(kind, rng)) for kind in kinds])
    pooled = {"plain": pooled_tree(trees), "weighted": pooled_tree(trees, weights=weights.tolist())}
    row = {
        f"{method}/{taste}": compare(truth[taste], tree).match_agreement
        for method, tree in pooled.items()
        for taste in TASTES
    }
    for kind in CROWD:
        row[f"weight/{kind}"] = float(weights[[k == kind for k in kinds]].sum() / weights.sum())
    return row
