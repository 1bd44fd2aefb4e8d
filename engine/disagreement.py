"""Disagreement pairs: extra pairs asked after the bracket, where a participant's own advice
and a no-advice baseline disagree most clearly (issue 25 §5, docs/method.md §2.12).

This is disagreement sampling as in BPref and PEBBLE (Lee et al. 2021): ask for labels where
two models of the answer disagree, because those labels carry the most information. Here the
two models are the participant's advice F at the candidates (known once their bracket is
done: the tree's reward grows with the rounds a candidate won) and a trained no-advice
baseline's score (its return from the candidate). A pair where they disagree is a match that
can tell an agent that used the advice from one that did not: the verdict counts the answered
pairs as matches of the advice (:func:`engine.verdict.split_matches`). They never enter the
tree.

A pair ``(i, j)`` qualifies when the advice prefers ``i`` and the baseline prefers ``j``, each
by at least its margin, a share of that score's spread over the candidates (the verdict's
margins, :class:`engine.verdict.VerdictOptions`); pairs already played in the bracket are left
out. Pairs are ranked by their *clarity*, the smaller of the two leads as shares of their
spreads, largest first; ties go to the lower ids, so the choice is deterministic.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from engine.errors import InputError

#: Most disagreement pairs a study may ask for.
MAX_PAIRS = 10


def disagreement_pairs(
    advice: np.ndarray,
    baseline: np.ndarray,
    *,
    k: int,
    played: Iterable[tuple[int, int]] = (),
    margin_advice: float = 0.05,
    margin_baseline: float = 0.05,
) -> list[tuple[int, int]]:
    """The ``k`` pairs where advice and baseline disagree most clearly, clearest first.

    Args:
        advice: the advice's score per candidate, shape ``(N,)`` (ids ``0 .. N-1``).
        baseline: the no-advice baseline's score per candidate, shape ``(N,)``.
        k: how many pairs at most (fewer when fewer pairs disagree).
        played: pairs the participant already decided (either order); left out.
        margin_advice: share of the advice's spread that its preference must reach.
        margin_baseline: share of the baseline's spread that its preference must reach.

    Returns:
        ``(advice's pick, baseline's pick)`` per pair.
    """
    advice, baseline = np.asarray(advice, dtype=float), np.asarray(baseline, dtype=float)
    if advice.ndim != 1 or advice.shape != baseline.shape:
        raise InputError("advice and baseline scores must be flat arrays of one length")
    if not 0 <= k <= MAX_PAIRS:
        raise InputError(f"disagreement pairs must be in 0..{MAX_PAIRS}, got {k}")
    lead = _shares(advice)[:, None] - _shares(advice)[None, :]  # [i, j]: advice's lead of i
    base_lead = _shares(baseline)[None, :] - _shares(baseline)[:, None]  # baseline's lead of j
    clarity = np.minimum(lead, base_lead)
    qualifies = (lead > 0) & (base_lead > 0) & (lead >= margin_advice)
    qualifies &= base_lead >= margin_baseline
    for a, b in played:
        qualifies[a, b] = qualifies[b, a] = False
    i, j = np.nonzero(qualifies)
    order = np.lexsort((j, i, -clarity[i, j]))[:k]  # clearest first, then lower ids
    return [(int(i[o]), int(j[o])) for o in order]


def _shares(scores: np.ndarray) -> np.ndarray:
    """Scores as shares of their spread (all 0 when every score is the same)."""
    spread = float(np.ptp(scores))
    return (scores - scores.min()) / spread if spread > 0 else np.zeros_like(scores)
