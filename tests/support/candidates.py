"""Small candidate sets built by hand (no env needed), and a bracket judged by their R."""

from __future__ import annotations

import numpy as np

from engine.bracket import Bracket, make_first_round
from engine.candidates import Candidate
from engine.tournament import ScoreJudge, play
from engine.treefile import TreeDocument, make_document


def make_candidates(n: int, rng: np.random.Generator | None = None) -> list[Candidate]:
    """``n`` candidates with distinct random rewards and 3-dim states."""
    rng = rng or np.random.default_rng(0)
    rewards = rng.permutation(n).astype(float)
    return [
        Candidate(i, rng.normal(size=5), rng.normal(size=4), float(rewards[i])) for i in range(n)
    ]


def r_judged_doc(n: int = 16, seed: int = 0) -> TreeDocument:
    """A complete bracket over :func:`make_candidates` judged (and scored) by their R."""
    rng = np.random.default_rng(seed)
    cands = make_candidates(n, rng)
    scores = {c.id: c.env_reward for c in cands}
    first = make_first_round(list(range(n)), np.array(list(scores.values())), 0.9, rng)
    results = play(Bracket(first), {c.id: c for c in cands}, ScoreJudge(scores))
    return make_document(
        env_id="Hopper-v5",
        seed=seed,
        p=0.9,
        judge="good",
        candidates=cands,
        first_round=first,
        results=results,
        scores=scores,
    )
