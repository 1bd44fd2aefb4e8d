"""The advice reward F(s): the Human Preference Tree generalised to any state.

Each tree node s' carries ``T_r(s') * D(s')`` (tree reward times depth factor). A state s is
compared with the nodes by cosine similarity of standardised posture features (docs/method.md
section 2):

- ``nearest`` (default): ``F(s) = sim(s, s*) * T_r(s*) * D(s*)``, ``s* = argmax sim(s, s')``.
- ``softmax``: the ``softmax(kappa * sim)``-weighted mean of ``T_r(s') * D(s')``.
- ``paper-min``: the paper's literal ``min_s' sim(s, s') * T_r(s') * D(s')`` (an ablation:
  with negative leaf rewards it mostly returns ``-r_b`` times the best leaf match).

Depth factor D: ``none`` (1) or ``paper`` (the node's depth, as in the paper; it lets the
runner-up at depth 2 outscore the champion at depth 1, so it is not the default).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from engine.envs import env_model
from engine.errors import InputError
from engine.rewards import posture_slice
from engine.treefile import TreeDocument

AdviceMode = Literal["nearest", "softmax", "paper-min"]
ADVICE_MODES: tuple[str, ...] = ("nearest", "softmax", "paper-min")
DEPTH_FACTORS: tuple[str, ...] = ("none", "paper")


@dataclass(frozen=True)
class AdviceReward:
    """Vectorised F(s) over a batch of states.

    Attributes:
        node_features: unit-norm standardised features of the tree's nodes, shape ``(N, d)``.
        node_values: ``T_r(s') * D(s')`` per node, shape ``(N,)``.
        mean: feature mean over the candidates, shape ``(d,)``.
        std: feature std over the candidates (1 where constant), shape ``(d,)``.
        posture: the slice of ``qpos`` that makes the features.
        mode: one of :data:`ADVICE_MODES`.
        kappa: softmax inverse temperature (``softmax`` mode only).
    """

    node_features: np.ndarray
    node_values: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    posture: slice
    mode: AdviceMode = "nearest"
    kappa: float = 10.0

    @classmethod
    def from_tree(
        cls,
        doc: TreeDocument,
        mode: AdviceMode = "nearest",
        depth_factor: str = "none",
        kappa: float = 10.0,
    ) -> AdviceReward:
        """F from a Human Preference Tree document."""
        if mode not in ADVICE_MODES:
            raise InputError(f"unknown advice mode {mode!r}: expected one of {ADVICE_MODES}")
        if depth_factor not in DEPTH_FACTORS:
            raise InputError(f"unknown depth factor {depth_factor!r}: expected {DEPTH_FACTORS}")
        posture = posture_slice(env_model(doc.env_id))
        feats = np.stack([c.qpos[posture] for c in doc.candidates])
        mean, std = feats.mean(0), feats.std(0)
        std = np.where(std > 1e-8, std, 1.0)
        nodes = doc.tree.nodes
        values = np.array(
            [
                nodes[c.id].reward * (nodes[c.id].depth if depth_factor == "paper" else 1.0)
                for c in doc.candidates
            ]
        )
        return cls(_unit((feats - mean) / std), values, mean, std, posture, mode, kappa)

    def similarity(self, qpos: np.ndarray) -> np.ndarray:
        """Cosine similarity of each state to each node, shape ``(B, N)``."""
        feats = np.atleast_2d(np.asarray(qpos, dtype=np.float64))[:, self.posture]
        similarity: np.ndarray = _unit((feats - self.mean) / self.std) @ self.node_features.T
        return similarity

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """F(s) for a batch of states: ``qpos`` shape ``(B, nq)`` -> shape ``(B,)``."""
        sim = self.similarity(qpos)
        if self.mode == "nearest":
            best = sim.argmax(axis=1)
            nearest: np.ndarray = sim[np.arange(len(sim)), best] * self.node_values[best]
            return nearest
        if self.mode == "softmax":
            logits = self.kappa * sim
            w = np.exp(logits - logits.max(axis=1, keepdims=True))
            softmax: np.ndarray = (w * self.node_values).sum(1) / w.sum(1)
            return softmax
        paper_min: np.ndarray = (sim * self.node_values).min(axis=1)
        return paper_min


@dataclass(frozen=True)
class PooledAdvice:
    """The advice of several people over one bracket: F is the mean of their trees' F.

    Attributes:
        members: one F per person (for example :class:`AdviceReward` of each tree).
        weights: one per member, such as each person's reliability
            (:func:`engine.reliability.competence`); None for the plain mean.
    """

    members: tuple[Callable[[np.ndarray], np.ndarray], ...]
    weights: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.weights is not None and (
            len(self.weights) != len(self.members)
            or min(self.weights) < 0
            or sum(self.weights) <= 0
        ):
            raise InputError("pool weights must be one per member, >= 0, and not all 0")

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """Mean F over the members, weighted when ``weights`` are given: ``qpos`` shape
        ``(B, nq)`` -> shape ``(B,)``."""
        values = [np.asarray(f(qpos), dtype=np.float64) for f in self.members]
        mean: np.ndarray = np.average(values, axis=0, weights=self.weights)
        return mean


def _unit(x: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(x, axis=-1, keepdims=True)
    return x / np.where(norm > 1e-12, norm, 1.0)
