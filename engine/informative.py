"""The ``informative`` candidate sampling mode: states on which a no-advice agent has a clear
preference, spread over its return and diverse in posture (issue 25 §5, docs/method.md §2.1).

1. **Pool.** Half of the rollout steps follow the trained no-advice *baseline*'s deterministic
   policy (its action mean, clipped to the action space), half take uniform random actions.
   Both restart with reset seeds drawn from the study's rng in
   ``[CANDIDATE_SEED_LOW, 2**31)``. The judges reset with their own option seeds plus an
   episode index (the behaviour judge: ``RolloutOptions.seed + k``, 0..9 by default; the
   return judge: ``ReturnOptions.seed``, 0 by default), always below ``CANDIDATE_SEED_LOW``
   in use, so no candidate rollout replays an evaluation episode. Of all visited states,
   ``POOL_PER_CANDIDATE * n`` are kept, half from each source (uniformly, without
   replacement).
2. **Estimate.** Each pooled state's *baseline return*: the baseline's Monte Carlo
   return-to-go from the restored state, the mean over 5 rollouts of at most 100 steps with
   small seeded perturbations, exactly as the ``return`` judge reads an agent
   (:func:`engine.rl.returns.state_returns`, default :class:`~engine.rl.returns.ReturnOptions`
   with a seed drawn from the rng). Not the critic: a critic extrapolates at states its agent
   never visits, and half of the pool are states of a random policy that the baseline never
   reaches. Rolling out the policy from them costs time (up to ``pool * 500`` env steps) but
   reads the policy itself, the same quantity the verdict's ``return`` judge scores.
3. **Pick.** The estimate's range over the pool is cut into ``n`` strata of equal width. Each
   stratum gets one candidate; an empty stratum takes its state from the nearest stratum that
   still has unpicked states. Strata are visited in an order drawn from the rng; the first
   stratum's state is drawn uniformly, each later one is the eligible state farthest (the
   largest minimum Euclidean distance) in standardised posture features from those already
   picked. So the candidates span the baseline's returns from its worst to its best state,
   and within that, differ in posture.
4. **Seeding.** Each candidate's ``seed_score`` is its estimate: the bracket's
   Braverman-Mossel seeding uses it as ability (:func:`engine.candidates.seed_abilities`), so
   that, at p = 0, seed k meets seed N + 1 - k in the first round (high against low).

Equal-width strata rather than equal-count quantiles: the pool's returns are often bimodal
(fallen states near 0, upright ones high), and quantile bins would then put most candidates
in one mode, where the baseline has no real preference between them.

This mode reads a trained policy's returns, so it sits above :mod:`engine.rl`, and above the
pure sampler (:mod:`engine.candidates`), whose candidates it makes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import gymnasium as gym
import numpy as np

from engine.candidates import Candidate, Policy, candidate_at, check_request, visit_steps
from engine.envs import make_env
from engine.gym_types import box, mujoco_base
from engine.rewards import posture_features
from engine.rl.returns import ReturnOptions, state_returns

#: Lowest reset seed of the candidate rollouts; the judges' evaluation seeds stay below it.
CANDIDATE_SEED_LOW = 2**30
#: Pooled states per candidate (the pool's size is this times ``n``).
POOL_PER_CANDIDATE = 6


@dataclass(frozen=True, eq=False)
class Pool:
    """Visited states the candidates are picked from.

    Attributes:
        qpos: positions, shape ``(P, nq)``.
        qvel: velocities, shape ``(P, nv)``.
        from_baseline: whether the baseline's policy (not a random one) visited it, ``(P,)``.
        estimate: the baseline's return from each state, shape ``(P,)``.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    from_baseline: np.ndarray
    estimate: np.ndarray


def sample_informative(
    env_id: str,
    n: int,
    *,
    rng: np.random.Generator,
    rollout_steps: int | None = None,
    policy: Policy | None,
) -> list[Candidate]:
    """``n`` candidates on which the trained no-advice ``policy`` has a clear preference, each
    with its return estimate as ``seed_score`` (module docstring).

    Args:
        env_id: a Gymnasium MuJoCo env id.
        n: number of candidates, 2 .. :data:`engine.candidates.MAX_CANDIDATES`.
        rng: the only source of randomness (env seeds, actions, the pool, the pick).
        rollout_steps: env steps to visit, half with ``policy``; default
            :func:`engine.candidates.visit_steps`.
        policy: the baseline's deterministic policy, observation -> action (required).

    Raises:
        InputError: ``n`` out of range, an unknown env, or no policy.
    """
    check_request(n, "informative", policy)
    assert policy is not None  # checked above
    pool = informative_pool(env_id, n, rollout_steps or visit_steps(n), rng, policy)
    env = make_env(env_id)
    try:
        features = posture_features(pool.qpos, mujoco_base(env).model)
        picked = pick_informative(pool.estimate, features, n, rng)
        return [
            replace(
                candidate_at(env, i, pool.qpos[j], pool.qvel[j]),
                seed_score=float(pool.estimate[j]),
            )
            for i, j in enumerate(picked)
        ]
    finally:
        env.close()


def informative_pool(
    env_id: str, n: int, steps: int, rng: np.random.Generator, baseline: Policy
) -> Pool:
    """Visit ``steps`` states (half with ``baseline``, half at random), keep
    ``POOL_PER_CANDIDATE * n`` of them and estimate the baseline's return from each."""
    env = make_env(env_id)
    try:
        space = box(env.action_space)
        space.seed(int(rng.integers(CANDIDATE_SEED_LOW, 2**31)))
        half = max(steps // 2, n)
        per_source = min(half, POOL_PER_CANDIDATE * n // 2)
        picked_q, picked_v, source = [], [], []
        for is_baseline in (True, False):
            policy: Policy = (
                (lambda obs: baseline(obs).clip(space.low, space.high))
                if is_baseline
                else (lambda obs: space.sample())
            )
            qpos, qvel = _visit(env, half, rng, policy)
            keep = np.sort(rng.choice(len(qpos), size=per_source, replace=False))
            picked_q.append(qpos[keep])
            picked_v.append(qvel[keep])
            source.append(np.full(per_source, is_baseline))
    finally:
        env.close()
    qpos, qvel = np.concatenate(picked_q), np.concatenate(picked_v)
    options = ReturnOptions(seed=int(rng.integers(2**31)))
    estimate = state_returns(baseline, env_id, qpos, qvel, options).mean(axis=1)
    return Pool(qpos, qvel, np.concatenate(source), estimate)


def _visit(
    env: gym.Env[Any, Any], steps: int, rng: np.random.Generator, policy: Policy
) -> tuple[np.ndarray, np.ndarray]:
    """``steps`` states visited by ``policy``, resetting with seeds from ``rng``."""
    obs, _ = env.reset(seed=int(rng.integers(CANDIDATE_SEED_LOW, 2**31)))
    qpos, qvel = [], []
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        qpos.append(mujoco_base(env).data.qpos.copy())
        qvel.append(mujoco_base(env).data.qvel.copy())
        if terminated or truncated:
            obs, _ = env.reset(seed=int(rng.integers(CANDIDATE_SEED_LOW, 2**31)))
    return np.array(qpos), np.array(qvel)


def pick_informative(
    estimate: np.ndarray, features: np.ndarray, n: int, rng: np.random.Generator
) -> np.ndarray:
    """Indices of ``n`` distinct states spread over ``estimate`` and far apart in posture.

    Args:
        estimate: the baseline's return per pooled state, shape ``(P,)``, ``P >= n``.
        features: posture features per pooled state, shape ``(P, d)``.
        n: states to pick.
        rng: the order of the strata and the first pick.

    Returns:
        shape ``(n,)``, in stratum order (lowest estimate first).
    """
    estimate = np.asarray(estimate, dtype=np.float64)
    z = (features - features.mean(0)) / (features.std(0) + 1e-8)
    low, width = estimate.min(), np.ptp(estimate) / n
    stratum = (
        np.minimum(((estimate - low) / width).astype(int), n - 1)
        if width > 0
        else np.arange(len(estimate)) * n // len(estimate)
    )
    free = np.ones(len(estimate), dtype=bool)
    picked: dict[int, int] = {}
    for k in (int(k) for k in rng.permutation(n)):
        eligible = _eligible(stratum, free, k, n)
        if not picked:
            choice = int(rng.choice(eligible))
        else:
            chosen = z[list(picked.values())]
            dist = np.sqrt(((z[eligible, None, :] - chosen[None]) ** 2).sum(-1)).min(axis=1)
            choice = int(eligible[int(np.argmax(dist))])
        picked[k] = choice
        free[choice] = False
    return np.array([picked[k] for k in range(n)])


def _eligible(stratum: np.ndarray, free: np.ndarray, k: int, n: int) -> np.ndarray:
    """Unpicked states of stratum ``k``, else of the nearest stratum that has some (the lower
    one first on a tie)."""
    for gap in range(n):
        for s in (k - gap, k + gap):
            found = np.flatnonzero(free & (stratum == s))
            if len(found):
                return found
    raise AssertionError("fewer pooled states than candidates")  # P >= n is checked upstream
