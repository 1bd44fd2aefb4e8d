"""The behaviour judge: which of the advised postures the agent actually adopts.

The other judges read the agent's reward or value at the candidate states; this one reads what
the agent *does*. The checkpoint's deterministic policy (the action mean, clipped to the action
space) is rolled out from the env's reset, seeded, for ``episodes`` episodes or ``max_steps``
steps, whichever comes first, and the first ``burn_in`` steps after each reset are dropped.
A candidate's score is the agent's mean occupancy near it: the
mean, over every visited state, of the cosine similarity that F uses (same posture features,
standardised over the bracket's candidates). In each match the candidate the agent spends more
time near wins, so the tree it builds is a *revealed-preference* tree.

Why the burn-in: every policy starts near the env's initial pose, so without it the states
right after each reset, which say nothing about the agent, dominate the occupancy. A random
policy that falls then ranks the candidates much as a trained one does (on Humanoid-v5 it kept
12 of 15 of the ``standing`` teacher's matches). The default, 50 steps (0.75 s of Humanoid), is
longer than a fall from the initial pose takes to end a Humanoid-v5 episode (16 to 26 steps
under uniform random actions, 40 to 41 under zero action, seeds 0 to 9), so an agent that only
falls visits nothing and has no preference. A policy whose episodes all end
within the burn-in scores every candidate 0 (no preference: each match is a tie).

Rollouts are cached per checkpoint in the run directory (``rollouts/``, keyed by the
checkpoint's content hash: :mod:`engine.rl.judge_cache`), so the same call twice simulates once
and gives the same tree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from engine.advice import AdviceReward
from engine.envs import make_env
from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class RolloutOptions:
    """How the behaviour judge rolls out the policy.

    Attributes:
        episodes: episodes at most.
        max_steps: env steps at most, over all episodes.
        seed: seed of the first reset; episode ``k`` resets with ``seed + k``.
        burn_in: steps after each reset whose states are dropped (they count towards
            ``max_steps``); see the module docstring for the default.
    """

    episodes: int = 10
    max_steps: int = 5000
    seed: int = 0
    burn_in: int = 50

    def __post_init__(self) -> None:
        if self.episodes < 1 or self.max_steps < 1 or self.seed < 0 or self.burn_in < 0:
            raise InputError(
                "behaviour rollouts need episodes >= 1, max_steps >= 1, a seed >= 0 and "
                f"burn_in >= 0, got {self.episodes}, {self.max_steps}, {self.seed}, "
                f"{self.burn_in}"
            )

    @property
    def key(self) -> str:
        """Part of the cache file name."""
        return f"e{self.episodes}.s{self.max_steps}.seed{self.seed}.b{self.burn_in}"


def behaviour_cache_name(digest: str, options: RolloutOptions) -> str:
    """The judges' cache name (:mod:`engine.rl.judge_cache`) of the states a policy visits:
    by the content hash of what decides its actions (an ACV checkpoint, an imported ONNX
    model and its normalisation) and the rollout options."""
    return f"behaviour.{digest[:16]}.{options.key}"


def visited_states(
    policy: Callable[[np.ndarray], np.ndarray], env_id: str, options: RolloutOptions
) -> np.ndarray:
    """``qpos`` of every state the deterministic policy visits after the burn-in, shape
    ``(T, nq)`` (``T`` may be 0).

    Args:
        policy: observation -> action mean (clipped here to the action space).
        env_id: the env the agent trained on.
        options: episodes, step budget, seed and burn-in.
    """
    env = make_env(env_id)
    space = box(env.action_space)
    low, high = space.low, space.high
    visited: list[np.ndarray] = []
    steps = 0
    try:
        for episode in range(options.episodes):
            obs, _ = env.reset(seed=options.seed + episode)
            done, t = False, 0
            while not done and steps < options.max_steps:
                obs, _, terminated, truncated, _ = env.step(policy(obs).clip(low, high))
                steps, t = steps + 1, t + 1
                if t > options.burn_in:
                    visited.append(mujoco_base(env).data.qpos.copy())
                done = terminated or truncated
            if steps >= options.max_steps:
                break
        nq = mujoco_base(env).model.nq
    finally:
        env.close()
    return np.stack(visited) if visited else np.zeros((0, nq))


def occupancy_scores(visited_qpos: np.ndarray, doc: TreeDocument) -> dict[int, float]:
    """Each candidate's mean similarity to the visited states (F's features and kernel).

    Args:
        visited_qpos: states the agent visited, shape ``(T, nq)``.
        doc: the bracket whose candidates are scored.
    """
    if len(visited_qpos) == 0:  # nothing visited after the burn-in: no preference
        return {c.id: 0.0 for c in doc.candidates}
    kernel = AdviceReward.from_tree(doc)  # standardised over the bracket's candidates
    mean_sim = kernel.similarity(visited_qpos).mean(axis=0)  # (N,)
    return {c.id: float(s) for c, s in zip(doc.candidates, mean_sim, strict=True)}


def nearest_shares(similarity: np.ndarray) -> np.ndarray:
    """Occupancy in the strict sense: the share of visited states whose most similar
    candidate is each one, shape ``(N,)`` (a tie goes to the lower id, as ``argmax``);
    all 0 when nothing was visited. Validation round 2's secondary score beside the mean
    similarity of :func:`occupancy_scores` (docs/validation.md §6).

    Args:
        similarity: each visited state's cosine similarity to each candidate, shape
            ``(T, N)`` (:meth:`engine.advice.AdviceReward.similarity`).
    """
    n = similarity.shape[1]
    if not len(similarity):
        return np.zeros(n)
    shares: np.ndarray = np.bincount(similarity.argmax(axis=1), minlength=n) / len(similarity)
    return shares
