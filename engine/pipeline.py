"""End-to-end helpers: sample + seed + play a bracket, and replay it with another judge."""

from __future__ import annotations

import numpy as np

from engine.bracket import Bracket, make_first_round
from engine.candidates import (
    Candidate,
    Policy,
    SamplingMode,
    sample_candidates,
    seed_abilities,
)
from engine.envs import env_model
from engine.errors import check_seed
from engine.teachers import make_teacher
from engine.tournament import Judge, play
from engine.treefile import TreeDocument, make_document


def run_tournament(
    *,
    env_id: str,
    n_candidates: int,
    p: float,
    seed: int,
    teacher: str,
    noise: float = 0.0,
    sampling: SamplingMode = "uniform",
    r_b: float = 1.0,
    r_e: float = 1.0,
    policy: Policy | None = None,
) -> TreeDocument:
    """Sample candidates, BM-seed the bracket and let a simulated teacher play it.

    All randomness comes from one generator seeded with ``seed``, so the same arguments give
    the same document (for a deterministic ``policy``).

    Args:
        policy: observation -> action for the rollouts the candidates come from; random
            actions when None (see :func:`engine.candidates.sample_candidates`); for
            ``informative`` sampling, the no-advice baseline's policy, whose return estimate
            then seeds the bracket (:func:`engine.candidates.seed_abilities`).

    Raises:
        InputError: a bad argument (negative seed, N < 2, unknown env, teacher or mode).
    """
    rng = np.random.default_rng(check_seed(seed))
    candidates = sample_candidates(env_id, n_candidates, rng=rng, mode=sampling, policy=policy)
    return teacher_bracket(
        env_id, candidates, rng, p=p, seed=seed, teacher=teacher, noise=noise, r_b=r_b, r_e=r_e
    )


def teacher_bracket(
    env_id: str,
    candidates: list[Candidate],
    rng: np.random.Generator,
    *,
    p: float,
    seed: int,
    teacher: str,
    noise: float = 0.0,
    r_b: float = 1.0,
    r_e: float = 1.0,
) -> TreeDocument:
    """BM-seed the first round over ``candidates`` and let a simulated teacher play the
    bracket (``seed`` is only recorded in the document; ``rng`` draws everything)."""
    first_round = make_first_round([c.id for c in candidates], seed_abilities(candidates), p, rng)
    judge, scores = make_teacher(teacher, candidates, env_model(env_id), noise=noise, rng=rng)
    results = play(Bracket(first_round), {c.id: c for c in candidates}, judge)
    return make_document(
        env_id=env_id,
        seed=seed,
        p=p,
        judge=_name(teacher, noise),
        candidates=candidates,
        first_round=first_round,
        results=results,
        r_b=r_b,
        r_e=r_e,
        scores=scores,
    )


def replay_with_teacher(doc: TreeDocument, teacher: str, noise: float = 0.0) -> TreeDocument:
    """Replay ``doc``'s bracket (same candidates, same first round) with a simulated teacher."""
    rng = np.random.default_rng([doc.seed, 1])  # independent of the original teacher's noise
    judge, scores = make_teacher(
        teacher, doc.candidates, env_model(doc.env_id), noise=noise, rng=rng
    )
    return replay(doc, judge, _name(teacher, noise), scores=scores)


def replay(
    doc: TreeDocument, judge: Judge, judge_name: str, scores: dict[int, float] | None = None
) -> TreeDocument:
    """The same bracket judged by ``judge``: trees over it are comparable."""
    results = play(doc.bracket, doc.by_id, judge)
    return make_document(
        env_id=doc.env_id,
        seed=doc.seed,
        p=doc.p,
        judge=judge_name,
        candidates=doc.candidates,
        first_round=doc.first_round,
        results=results,
        r_b=doc.r_b,
        r_e=doc.r_e,
        scores=scores,
    )


def _name(teacher: str, noise: float) -> str:
    return teacher if noise == 0 else f"{teacher}+noise{noise:g}"
