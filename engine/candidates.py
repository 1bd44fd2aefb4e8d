"""Candidate states: sampled from rollouts, each a player in the bracket.

Modes (docs/method.md section 2): ``uniform`` picks N of all visited states uniformly;
``diverse`` clusters the visited states' standardised posture features with k-means and keeps
the state nearest each centroid (the paper's "future work" on more interpretable trees);
``informative`` pools states of a trained no-advice baseline's rollouts and of random ones,
and keeps N spread over the baseline's return and diverse in posture, each carrying that
return as its ``seed_score``.

This module is the pure sampler, ``uniform`` and ``diverse``, and the candidate every part of
the engine shares. ``informative`` reads a trained policy's returns
(:func:`engine.rl.returns.state_returns`), so it sits above the agents, in
:mod:`engine.informative`; :func:`engine.pipeline.sample_by_mode` samples in any mode.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import gymnasium as gym
import numpy as np

from engine.envs import DEFAULT_ENV_ID, make_env, restore
from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.rewards import posture_features, state_reward

SamplingMode = Literal["uniform", "diverse", "informative"]
SAMPLING_MODES: tuple[str, ...] = ("uniform", "diverse", "informative")
#: The modes this module samples: they need no trained policy's returns.
PureMode = Literal["uniform", "diverse"]
PURE_MODES: tuple[str, ...] = ("uniform", "diverse")
#: The modes that need a trained no-advice baseline's policy.
BASELINE_MODES: tuple[str, ...] = ("informative",)
MAX_CANDIDATES = 128

#: A policy for rollouts: observation -> action. ``None`` means uniform random actions.
Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class Candidate:
    """A player of the bracket: one stored state.

    Attributes:
        id: position in the study's candidate list, ``0 .. N-1``.
        qpos: generalised positions, shape ``(nq,)``.
        qvel: generalised velocities, shape ``(nv,)``.
        env_reward: R(s), its ability in Braverman-Mossel seeding unless ``seed_score`` is
            given.
        seed_score: its ability in Braverman-Mossel seeding instead of R(s), when not None
            (``informative`` sampling: the baseline's return from the state). Not stored:
            it only places the candidate in the first round.
    """

    id: int
    qpos: np.ndarray
    qvel: np.ndarray
    env_reward: float
    seed_score: float | None = None


def seed_abilities(candidates: Sequence[Candidate]) -> np.ndarray:
    """Each candidate's ability in Braverman-Mossel seeding, shape ``(N,)``: its
    ``seed_score`` when it has one, else its R(s)."""
    return np.array(
        [c.env_reward if c.seed_score is None else c.seed_score for c in candidates],
        dtype=np.float64,
    )


def check_request(n: int, mode: str, policy: Policy | None) -> None:
    """Refuse a number of candidates out of range, an unknown mode, or ``informative``
    sampling without a baseline policy.

    Raises:
        InputError: the request names one of those.
    """
    if not 2 <= n <= MAX_CANDIDATES:
        raise InputError(f"number of candidates must be in 2..{MAX_CANDIDATES}, got {n}")
    if mode not in SAMPLING_MODES:
        raise InputError(f"unknown sampling mode {mode!r}: expected one of {SAMPLING_MODES}")
    if mode == "informative" and policy is None:
        raise InputError(
            "informative sampling needs a trained no-advice baseline's policy: "
            "train a ppo run on this env first"
        )


def visit_steps(n: int) -> int:
    """Env steps visited for ``n`` candidates when the caller names none."""
    return max(2000, 50 * n)


def sample_candidates(
    env_id: str = DEFAULT_ENV_ID,
    n: int = 16,
    *,
    rng: np.random.Generator,
    mode: PureMode = "uniform",
    rollout_steps: int | None = None,
    policy: Policy | None = None,
) -> list[Candidate]:
    """Roll out ``policy`` in the env and pick ``n`` candidate states from those visited.

    Args:
        env_id: a Gymnasium MuJoCo env id.
        n: number of candidates, 2 ..  :data:`MAX_CANDIDATES`.
        rng: the only source of randomness (env seeds, actions, the pick).
        mode: ``uniform`` or ``diverse`` (``informative``:
            :func:`engine.informative.sample_informative`).
        rollout_steps: env steps to visit; default :func:`visit_steps`.
        policy: observation -> action; random actions when ``None``.

    Raises:
        InputError: ``n`` out of range, an unknown mode or env, or ``informative``.
    """
    check_request(n, mode, policy)
    if mode not in PURE_MODES:
        raise InputError(
            f"{mode} sampling reads a trained policy's returns: "
            "engine.pipeline.sample_by_mode samples in every mode"
        )
    env = make_env(env_id)
    try:
        qpos, qvel = _rollout(env, rollout_steps or visit_steps(n), rng, policy)
        features = posture_features(qpos, mujoco_base(env).model)
        picked = (
            _pick_uniform(len(qpos), n, rng)
            if mode == "uniform"
            else _pick_diverse(features, n, rng)
        )
        return [candidate_at(env, i, qpos[j], qvel[j]) for i, j in enumerate(picked)]
    finally:
        env.close()


def _rollout(
    env: gym.Env[Any, Any], steps: int, rng: np.random.Generator, policy: Policy | None
) -> tuple[np.ndarray, np.ndarray]:
    """Visit ``steps`` states over as many episodes as needed; returns (qpos, qvel) stacks."""
    env.action_space.seed(int(rng.integers(2**31)))
    obs, _ = env.reset(seed=int(rng.integers(2**31)))
    qpos, qvel = [], []
    for _ in range(steps):
        action = env.action_space.sample() if policy is None else policy(obs)
        obs, _, terminated, truncated, _ = env.step(action)
        qpos.append(mujoco_base(env).data.qpos.copy())
        qvel.append(mujoco_base(env).data.qvel.copy())
        if terminated or truncated:
            obs, _ = env.reset(seed=int(rng.integers(2**31)))
    return np.array(qpos), np.array(qvel)


def _pick_uniform(visited: int, n: int, rng: np.random.Generator) -> np.ndarray:
    return np.sort(rng.choice(visited, size=n, replace=False))


def _pick_diverse(features: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """One visited state per k-means cluster: the one nearest its centroid."""
    from sklearn.cluster import KMeans  # deferred: importing sklearn costs ~0.8 s

    z = (features - features.mean(0)) / (features.std(0) + 1e-8)
    km = KMeans(n_clusters=n, n_init=4, random_state=int(rng.integers(2**31))).fit(z)
    dist = ((z[None, :, :] - km.cluster_centers_[:, None, :]) ** 2).sum(-1)  # (n, visited)
    picked: list[int] = []
    for row in dist:  # nearest not yet picked: two centroids may share a nearest state
        order = np.argsort(row)
        picked.append(int(next(j for j in order if j not in picked)))
    return np.sort(np.array(picked))


def random_actions(env_id: str, seed: int) -> Policy:
    """A policy of uniform random actions drawn from ``seed`` alone, so that the same seed
    gives the same actions: what rolls a uniform or diverse study's candidates forward in
    their clips (random actions sampled them). Each call starts a fresh generator."""
    env = make_env(env_id)
    try:
        space = box(env.action_space)
        low, high = np.asarray(space.low), np.asarray(space.high)
    finally:
        env.close()
    rng = np.random.default_rng(seed)
    return lambda _obs: rng.uniform(low, high)


def candidate_at(env: gym.Env[Any, Any], cid: int, qpos: np.ndarray, qvel: np.ndarray) -> Candidate:
    """Candidate ``cid`` at ``(qpos, qvel)``, its R(s) read from ``env`` restored there."""
    restore(env, qpos, qvel)
    return Candidate(id=cid, qpos=qpos, qvel=qvel, env_reward=state_reward(env))
