"""Pooled advice: several people's Preference Trees over one bracket as one advice.

Participants of a study label the same bracket (same candidates, same first round), so their
trees are comparable and their advice can be pooled: F is the mean of their trees' F
(:class:`engine.advice.PooledAdvice`). The *pooled verdict* is the bracket replayed with that
mean as the score: at a candidate each tree's F is its own tree reward, so the pooled verdict
ranks candidates by the mean of the rounds they won across people.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from engine.advice import AdviceReward, PooledAdvice
from engine.conformance import check_same_bracket
from engine.errors import InputError
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument, replay


def check_pool(docs: Sequence[TreeDocument]) -> None:
    """Raise :class:`InputError` unless ``docs`` are two or more trees over one bracket."""
    if len(docs) < 2:
        raise InputError("pooled advice needs at least two trees")
    for doc in docs[1:]:
        check_same_bracket(docs[0], doc)


def pooled_advice(
    docs: Sequence[TreeDocument],
    mode: str = "nearest",
    depth_factor: str = "none",
    kappa: float = 10.0,
    *,
    weights: Sequence[float] | None = None,
) -> PooledAdvice:
    """F of the pool: the mean of each tree's :class:`AdviceReward` (same options for all),
    weighted by ``weights`` (one per tree) when given."""
    check_pool(docs)
    return PooledAdvice(
        tuple(
            AdviceReward.from_tree(
                d,
                mode=mode,  # type: ignore[arg-type]
                depth_factor=depth_factor,
                kappa=kappa,
            )
            for d in docs
        ),
        None if weights is None else tuple(float(w) for w in weights),
    )


def pooled_tree(
    docs: Sequence[TreeDocument],
    mode: str = "nearest",
    depth_factor: str = "none",
    kappa: float = 10.0,
    *,
    weights: Sequence[float] | None = None,
) -> TreeDocument:
    """The pooled verdict: the shared bracket replayed by the pool's mean F at each candidate,
    with the F options the run trains with (:func:`pooled_advice`), weighted when
    ``weights`` are given.

    Its ``judge`` is ``pooled:<judge>,<judge>,...``; its scores are the mean F.
    """
    f = pooled_advice(docs, mode, depth_factor, kappa, weights=weights)
    base = docs[0]
    values = f(np.stack([c.qpos for c in base.candidates]))
    scores = {c.id: float(v) for c, v in zip(base.candidates, values, strict=True)}
    return replay(
        base, ScoreJudge(scores), "pooled:" + ",".join(d.judge for d in docs), scores=scores
    )
