"""Specificity of the whole-bracket verdict (:mod:`engine.verdict_bracket`): does a run follow
*this* tree more than trees that merely share its candidates? Reported beside the verdict,
never deciding (docs/validation.md §6.2), and the source of round 2's unrelated shuffled
trees (:func:`engine.validation.round2.unrelated_tree`).
"""

from __future__ import annotations

import numpy as np

from engine.bracket import Bracket
from engine.preference_tree import from_dendrogram
from engine.tournament import dendrogram
from engine.treefile import TreeDocument
from engine.verdict_bracket import alignment, tree_values


def coin_results(bracket: Bracket, rng: np.random.Generator) -> dict[tuple[int, int], int]:
    """A complete set of results for ``bracket``, each match won by a fair coin."""
    results: dict[tuple[int, int], int] = {}
    while open_ := bracket.open_matches(results):
        for m in open_:
            results[(m.round, m.slot)] = m.a if rng.random() < 0.5 else m.b
    return results


def random_tree_values(doc: TreeDocument, count: int, rng: np.random.Generator) -> np.ndarray:
    """T_r of ``count`` trees over the same bracket (its first round and byes), each match won
    by a fair coin, shape ``(count, N)``: what trees that merely share the candidates say."""
    bracket, ids = Bracket(doc.first_round), [c.id for c in doc.candidates]
    out = np.empty((count, len(ids)))
    for i in range(count):
        root = dendrogram(bracket, coin_results(bracket, rng))
        tree = from_dendrogram(root, r_b=doc.r_b, r_e=doc.r_e)
        out[i] = [tree.nodes[c].reward for c in ids]
    return out


def specificity(
    scores: np.ndarray, doc: TreeDocument, rng: np.random.Generator, trees: int = 1000
) -> np.ndarray:
    """Each run's percentile of the person's tree among random trees over the same bracket:
    the share of ``trees`` coin-flip trees the run lines up with less than with the person's
    (ties half). Near 1: the run follows *this* tree, not any tree of these candidates.

    Args:
        scores: the judge's scores, shape ``(k, N)``.
        doc: the person's tree.
        rng: draws the random trees.
        trees: how many random trees.

    Returns:
        shape ``(k,)``, in [0, 1].
    """
    own = alignment(scores, tree_values(doc))[:, None]  # (k, 1)
    others = alignment(scores[:, None, :], random_tree_values(doc, trees, rng)[None])  # (k, T)
    share: np.ndarray = (others < own).mean(axis=1) + 0.5 * (others == own).mean(axis=1)
    return share
