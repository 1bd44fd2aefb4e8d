"""Synthetic agents over a real bracket, whose answer is known, for the whole-bracket verdict's
tests and power (issue 40 §1; docs/validation.md §6).

A synthetic agent is where it spends its time. Each run has its own taste over the bracket's
candidates, logits ``shift * z + Normal(0, taste_sd)`` (``z``: the tree's T_r standardised),
and visits ``visits`` states, each one candidate's posture (drawn by the softmax of those
logits) plus Gaussian posture noise. Its scores are then computed from the visited states as
the behaviour judge computes them: the mean cosine similarity in F's features (the primary)
and the share of states nearest each candidate (the secondary). So the verdict meets what a
real bracket gives it (16 candidates, ties and zeros of occupancy, bounded scores), not a
per-seed number drawn directly. ``shift > 0`` agents follow the tree, ``shift < 0`` agents
go against it, ``shift = 0`` agents ignore it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.advice import AdviceReward
from engine.rl.behaviour import nearest_shares
from engine.treefile import TreeDocument
from engine.verdict_bracket import tree_values


@dataclass(frozen=True)
class SyntheticAgents:
    """One arm of synthetic agents.

    Attributes:
        shift: how strongly the arm's taste follows the tree (negative: against it).
        taste_sd: each run's own taste per candidate, the spread between seeds.
        visits: visited states per run.
        posture_noise: the visited states' noise, in units of the candidates' feature spread.
    """

    shift: float = 0.0
    taste_sd: float = 1.0
    visits: int = 100
    posture_noise: float = 0.5


@dataclass(frozen=True)
class Scores:
    """An arm's judge scores over the bracket's ``N`` candidates.

    Attributes:
        similarity: mean cosine similarity per run and candidate, shape ``(k, N)``.
        nearest: the share of visited states nearest each candidate, shape ``(k, N)``.
    """

    similarity: np.ndarray
    nearest: np.ndarray


class SyntheticBracket:
    """A real bracket made ready for drawing agents: its features, kernel and ``z``."""

    def __init__(self, doc: TreeDocument):
        self.kernel = AdviceReward.from_tree(doc)
        self.qpos = np.stack([c.qpos for c in doc.candidates])  # (N, nq)
        self.values = tree_values(doc)  # (N,)
        self.z = (self.values - self.values.mean()) / self.values.std()

    def draw(self, agents: SyntheticAgents, k: int, rng: np.random.Generator) -> Scores:
        """``k`` runs of ``agents`` on this bracket."""
        n, nq = self.qpos.shape
        logits = agents.shift * self.z + rng.normal(0, agents.taste_sd, (k, n))
        taste = np.exp(logits - logits.max(axis=1, keepdims=True))
        taste /= taste.sum(axis=1, keepdims=True)
        picks = (rng.random((k, agents.visits, 1)) > taste.cumsum(axis=1)[:, None, :]).sum(-1)
        noise = np.zeros((k, agents.visits, nq))
        noise[..., self.kernel.posture] = (
            rng.normal(0, agents.posture_noise, (k, agents.visits, len(self.kernel.std)))
            * self.kernel.std
        )
        visited = self.qpos[np.minimum(picks, n - 1)] + noise  # (k, T, nq)
        sims = self.kernel.similarity(visited.reshape(-1, nq)).reshape(k, agents.visits, n)
        return Scores(sims.mean(axis=1), np.stack([nearest_shares(s) for s in sims]))
