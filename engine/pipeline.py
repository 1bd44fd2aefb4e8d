"""End-to-end helpers: sample (in any mode) + seed + play a bracket, and replay it with a
simulated teacher.

Above the agents: ``informative`` sampling reads a trained policy's returns
(:mod:`engine.informative`). What the agents need of a bracket, replaying it with their own
judge, is :func:`engine.treefile.replay`, below them.
"""

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
from engine.informative import sample_informative
from engine.teachers import make_teacher
from engine.tournament import play
from engine.treefile import TreeDocument, make_document, replay


def sample_by_mode(
    env_id: str,
    n: int,
    *,
    rng: np.random.Generator,
    mode: SamplingMode = "uniform",
    rollout_steps: int | None = None,
    policy: Policy | None = None,
) -> list[Candidate]:
    """Candidates in any mode: ``informative`` by :func:`engine.informative.sample_informative`,
    ``uniform`` and ``diverse`` by the pure :func:`engine.candidates.sample_candidates`.

    Args:
        env_id: a Gymnasium MuJoCo env id.
        n: number of candidates, 2 .. :data:`engine.candidates.MAX_CANDIDATES`.
        rng: the only source of randomness.
        mode: ``uniform``, ``diverse`` or ``informative``.
        rollout_steps: env steps to visit; default :func:`engine.candidates.visit_steps`.
        policy: observation -> action, random actions when None; for ``informative``, the
            trained no-advice baseline's deterministic policy (required).

    Raises:
        InputError: ``n`` out of range, an unknown mode or env, or ``informative`` without
            a baseline policy.
    """
    if mode == "informative":
        return sample_informative(env_id, n, rng=rng, rollout_steps=rollout_steps, policy=policy)
    return sample_candidates(
        env_id, n, rng=rng, mode=mode, rollout_steps=rollout_steps, policy=policy
    )


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
            actions when None (see :func:`sample_by_mode`); for
            ``informative`` sampling, the no-advice baseline's policy, whose return estimate
            then seeds the bracket (:func:`engine.candidates.seed_abilities`).

    Raises:
        InputError: a bad argument (negative seed, N < 2, unknown env, teacher or mode).
    """
    rng = np.random.default_rng(check_seed(seed))
    candidates = sample_by_mode(env_id, n_candidates, rng=rng, mode=sampling, policy=policy)
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


def _name(teacher: str, noise: float) -> str:
    return teacher if noise == 0 else f"{teacher}+noise{noise:g}"
