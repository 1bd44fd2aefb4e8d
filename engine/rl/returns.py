"""The return judge: what the agent's own policy earns from each candidate state.

A candidate's score is the Monte Carlo return-to-go of the checkpoint's deterministic policy
(the action mean, clipped to the action space, on observations normalised as in training) from
the candidate's restored state: the mean, over ``rollouts`` rollouts, of the sum of the env's
own reward (the true R, with its control cost and healthy terms; never the shaped reward) over
at most ``horizon`` steps or until the env terminates. Each rollout starts from the candidate's
``(qpos, qvel)`` plus a small seeded perturbation, uniform in ``[-noise, noise]`` like the
env's own reset noise, so that the score is not one knife-edge trajectory.

Unlike the ``shaped-value`` judge, nothing is read off a critic at states the agent may never
visit, and nothing of the advice F enters: the judge asks which state the *agent* does better
from. Defaults: 5 rollouts of at most 100 steps (1.5 s of Humanoid, 0.8 s of Hopper) keep a
16-candidate bracket to seconds on one core (docs/method.md §2.9).

Scores are cached per checkpoint in the run directory, keyed by the checkpoint's content hash,
the candidates and the options (:mod:`engine.rl.judge_cache`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from engine.envs import make_env, restore
from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.rl.judge_cache import array_digest, cached_array
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class ReturnOptions:
    """How the return judge rolls out the policy from each candidate.

    Attributes:
        rollouts: rollouts per candidate (K >= 5: fewer would let one lucky fall decide).
        horizon: env steps per rollout at most (a rollout also ends when the env terminates).
        noise: half-width of the uniform perturbation added to the candidate's qpos and qvel;
            None for the env's own ``reset_noise_scale`` (1e-2 on Humanoid, 5e-3 on Hopper).
        seed: seed of the perturbations.
    """

    rollouts: int = 5
    horizon: int = 100
    noise: float | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if self.rollouts < 5 or self.horizon < 1 or self.seed < 0:
            raise InputError(
                "the return judge needs rollouts >= 5, horizon >= 1 and a seed >= 0, got "
                f"{self.rollouts}, {self.horizon}, {self.seed}"
            )
        if self.noise is not None and not 0 <= self.noise < 1:
            raise InputError(f"the return judge's noise must be in [0, 1), got {self.noise}")

    @property
    def key(self) -> str:
        """Part of the cache file name."""
        return f"k{self.rollouts}.h{self.horizon}.n{self.noise}.seed{self.seed}"


def candidate_returns(
    policy: Callable[[np.ndarray], np.ndarray],
    doc: TreeDocument,
    options: ReturnOptions,
) -> np.ndarray:
    """Return-to-go of ``policy`` from every candidate, shape ``(N, rollouts)``, in id order.

    Args:
        policy: observation -> action mean (clipped here to the action space).
        doc: the bracket whose candidates are the start states.
        options: rollouts, horizon, perturbation and seed.
    """
    return state_returns(policy, doc.env_id, *candidate_states(doc), options)


def candidate_states(doc: TreeDocument) -> tuple[np.ndarray, np.ndarray]:
    """The candidates' ``qpos`` and ``qvel``, shapes ``(N, nq)`` and ``(N, nv)``, in id order:
    the start states of the return judge's rollouts."""
    return np.stack([c.qpos for c in doc.candidates]), np.stack([c.qvel for c in doc.candidates])


def state_returns(
    policy: Callable[[np.ndarray], np.ndarray],
    env_id: str,
    qpos: np.ndarray,
    qvel: np.ndarray,
    options: ReturnOptions,
) -> np.ndarray:
    """Return-to-go of ``policy`` from each of a batch of states, shape ``(B, rollouts)``.

    Args:
        policy: observation -> action mean (clipped here to the action space).
        env_id: the env the states belong to.
        qpos: start positions, shape ``(B, nq)``.
        qvel: start velocities, shape ``(B, nv)``.
        options: rollouts, horizon, perturbation and seed.
    """
    rng = np.random.default_rng(options.seed)
    env = make_env(env_id)
    try:
        env.reset(seed=options.seed)
        space = box(env.action_space)
        noise = _noise(env) if options.noise is None else options.noise
        out = np.zeros((len(qpos), options.rollouts))
        for i, (q, v) in enumerate(zip(qpos, qvel, strict=True)):
            for k in range(options.rollouts):
                start_q = q + rng.uniform(-noise, noise, q.shape)
                start_v = v + rng.uniform(-noise, noise, v.shape)
                env.reset()  # restarts the time limit; the state is then replaced
                obs = restore(env, start_q, start_v)
                for _ in range(options.horizon):
                    obs, r, terminated, _, _ = env.step(policy(obs).clip(space.low, space.high))
                    out[i, k] += float(r)
                    if terminated:
                        break
    finally:
        env.close()
    return out


def _noise(env: gym.Env[Any, Any]) -> float:
    """The env's own reset noise scale (1e-2 when it has none)."""
    return float(getattr(mujoco_base(env), "_reset_noise_scale", 1e-2))


def return_scores(
    policy: Callable[[np.ndarray], np.ndarray],
    doc: TreeDocument,
    options: ReturnOptions,
    *,
    run_dir: Path | None = None,
    checkpoint_digest: str = "",
) -> dict[int, float]:
    """The return judge's scores: mean return-to-go per candidate id.

    Args:
        policy: the checkpoint's deterministic policy.
        doc: the bracket whose candidates are scored.
        options: the rollouts.
        run_dir: where the scores are cached (no cache when None or without a digest).
        checkpoint_digest: the checkpoint's content hash, the cache key.
    """
    returns = cached_array(
        run_dir if checkpoint_digest else None,
        return_cache_name(checkpoint_digest, doc, options),
        lambda: candidate_returns(policy, doc, options),
    )
    return mean_returns(doc, returns)


def return_cache_name(digest: str, doc: TreeDocument, options: ReturnOptions) -> str:
    """The judges' cache name (:mod:`engine.rl.judge_cache`) of a policy's returns from the
    candidates: by the content hash of what decides its actions, the candidates' states and
    the options."""
    states = [np.concatenate([c.qpos, c.qvel]) for c in doc.candidates]
    return f"return.{digest[:16]}.{array_digest(*states)}.{options.key}"


def mean_returns(doc: TreeDocument, returns: np.ndarray) -> dict[int, float]:
    """The return judge's score of each candidate id: its mean over the rollouts of
    ``returns``, shape ``(N, rollouts)`` in id order (:func:`candidate_returns`)."""
    means = returns.mean(axis=1)
    return {c.id: float(v) for c, v in zip(doc.candidates, means, strict=True)}
