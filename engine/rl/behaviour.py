"""The behaviour judge: which of the advised postures the agent actually adopts.

The other judges read the agent's reward or value at the candidate states; this one reads what
the agent *does*. The checkpoint's deterministic policy (the action mean, clipped to the action
space) is rolled out from the env's reset, seeded, for ``episodes`` episodes or ``max_steps``
steps, whichever comes first. A candidate's score is the agent's mean occupancy near it: the
mean, over every visited state, of the cosine similarity that F uses (same posture features,
standardised over the bracket's candidates). In each match the candidate the agent spends more
time near wins, so the tree it builds is a *revealed-preference* tree.

Rollouts are cached per checkpoint in the run directory (``rollouts/``), so the same call
twice simulates once and gives the same tree.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.advice import AdviceReward
from engine.envs import make_env
from engine.errors import InputError
from engine.gym_types import box, mujoco_base
from engine.treefile import TreeDocument

ROLLOUT_DIR = "rollouts"


@dataclass(frozen=True)
class RolloutOptions:
    """How the behaviour judge rolls out the policy.

    Attributes:
        episodes: episodes at most.
        max_steps: env steps at most, over all episodes.
        seed: seed of the first reset; episode ``k`` resets with ``seed + k``.
    """

    episodes: int = 10
    max_steps: int = 5000
    seed: int = 0

    def __post_init__(self) -> None:
        if self.episodes < 1 or self.max_steps < 1 or self.seed < 0:
            raise InputError(
                "behaviour rollouts need episodes >= 1, max_steps >= 1 and a "
                f"seed >= 0, got {self.episodes}, {self.max_steps}, {self.seed}"
            )

    @property
    def key(self) -> str:
        """Part of the cache file name."""
        return f"e{self.episodes}.s{self.max_steps}.seed{self.seed}"


def visited_states(
    policy: Callable[[np.ndarray], np.ndarray], env_id: str, options: RolloutOptions
) -> np.ndarray:
    """``qpos`` of every state the deterministic policy visits, shape ``(T, nq)``.

    Args:
        policy: observation -> action mean (clipped here to the action space).
        env_id: the env the agent trained on.
        options: episodes, step budget and seed.
    """
    env = make_env(env_id)
    space = box(env.action_space)
    low, high = space.low, space.high
    visited: list[np.ndarray] = []
    try:
        for episode in range(options.episodes):
            obs, _ = env.reset(seed=options.seed + episode)
            done = False
            while not done and len(visited) < options.max_steps:
                obs, _, terminated, truncated, _ = env.step(policy(obs).clip(low, high))
                visited.append(mujoco_base(env).data.qpos.copy())
                done = terminated or truncated
            if len(visited) >= options.max_steps:
                break
    finally:
        env.close()
    return np.stack(visited)


def occupancy_scores(visited_qpos: np.ndarray, doc: TreeDocument) -> dict[int, float]:
    """Each candidate's mean similarity to the visited states (F's features and kernel).

    Args:
        visited_qpos: states the agent visited, shape ``(T, nq)``.
        doc: the bracket whose candidates are scored.
    """
    kernel = AdviceReward.from_tree(doc)  # standardised over the bracket's candidates
    mean_sim = kernel.similarity(visited_qpos).mean(axis=0)  # (N,)
    return {c.id: float(s) for c, s in zip(doc.candidates, mean_sim, strict=True)}


def cached_visited_states(
    run_dir: Path | None, step: int, compute: Callable[[], np.ndarray], options: RolloutOptions
) -> np.ndarray:
    """:func:`visited_states` through the run directory's cache (best effort: a cache that
    cannot be written costs only time)."""
    if run_dir is None:
        return compute()
    path = Path(run_dir) / ROLLOUT_DIR / f"step_{step}.{options.key}.npy"
    if path.is_file():
        try:
            cached: np.ndarray = np.load(path)
            return cached
        except (OSError, ValueError):
            pass  # a damaged cache file is a miss
    visited = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npy")
        with os.fdopen(fd, "wb") as f:
            np.save(f, visited)
        os.replace(tmp, path)
    except OSError:
        pass
    return visited
