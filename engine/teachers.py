"""Simulated teachers: judges that stand in for a person in tests, demos and the paper's cases.

- ``good``: prefers the higher state reward R(s) (the paper's Case 1, F = R).
- ``standing``: prefers upright standing (the paper's Case 2, "bad" advice):
  ``exp(-((h - h0) / 0.1)^2) * clip((up + 1) / 1.9, 0, 1)`` with ``h`` the torso height,
  ``h0`` its height in the model's initial pose (1.4 for Humanoid) and ``up`` the torso's
  uprightness.
- ``orthogonal``: prefers a posture the environment's reward does not pay for (Humanoid:
  arms raised; Hopper: a bent knee; :mod:`engine.postures`), so that following it is
  something R cannot explain.
- ``random``: a fair coin per match.

Any teacher may flip each decision with probability ``noise``, mimicking human error.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import StrEnum
from typing import TYPE_CHECKING

import numpy as np

from engine.candidates import Candidate
from engine.errors import InputError
from engine.postures import orthogonal_score
from engine.rewards import posture_slice, torso_height, uprightness
from engine.tournament import Judge, ScoreJudge

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco


class Teacher(StrEnum):
    """The simulated teachers (this module's docstring says what each prefers)."""

    GOOD = "good"
    STANDING = "standing"
    ORTHOGONAL = "orthogonal"
    RANDOM = "random"


TEACHERS: tuple[str, ...] = tuple(t.value for t in Teacher)


def standing_score(qpos: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
    """How much a batch of states looks like upright standing, in [0, 1], shape ``(B,)``."""
    h0 = model.qpos0[2 if posture_slice(model).start == 2 else 1]
    height_term = np.exp(-(((torso_height(qpos, model) - h0) / 0.1) ** 2))
    score: np.ndarray = height_term * np.clip((uprightness(qpos, model) + 1.0) / 1.9, 0.0, 1.0)
    return score


POSTURE_SCORES = {"standing": standing_score, "orthogonal": orthogonal_score}


def teacher_scores(
    name: str, candidates: Sequence[Candidate], model: mujoco.MjModel
) -> dict[int, float] | None:
    """The scores a score-based teacher judges by; ``None`` for ``random``."""
    if name == "good":
        return {c.id: c.env_reward for c in candidates}
    if name in POSTURE_SCORES:
        scores = POSTURE_SCORES[name](np.stack([c.qpos for c in candidates]), model)
        return {c.id: float(s) for c, s in zip(candidates, scores, strict=True)}
    if name == "random":
        return None
    raise InputError(f"unknown teacher {name!r}: expected one of {', '.join(TEACHERS)}")


class CoinJudge:
    """A fair coin per match."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng

    def __call__(self, a: Candidate, b: Candidate) -> int:
        return a.id if self.rng.random() < 0.5 else b.id


class NoisyJudge:
    """Flips another judge's decision with probability ``noise``."""

    def __init__(self, judge: Judge, noise: float, rng: np.random.Generator):
        if not 0.0 <= noise <= 1.0:
            raise InputError(f"noise must be in [0, 1], got {noise}")
        self.judge, self.noise, self.rng = judge, noise, rng

    def __call__(self, a: Candidate, b: Candidate) -> int:
        winner = self.judge(a, b)
        if self.rng.random() < self.noise:
            return b.id if winner == a.id else a.id
        return winner


def make_teacher(
    name: str,
    candidates: Sequence[Candidate],
    model: mujoco.MjModel,
    *,
    noise: float = 0.0,
    rng: np.random.Generator,
) -> tuple[Judge, dict[int, float] | None]:
    """A simulated teacher and, for score-based ones, the scores it judges by."""
    if not 0.0 <= noise <= 1.0:
        raise InputError(f"noise must be in [0, 1], got {noise}")
    scores = teacher_scores(name, candidates, model)
    judge: Judge = CoinJudge(rng) if scores is None else ScoreJudge(scores)
    return (NoisyJudge(judge, noise, rng) if noise > 0 else judge), scores
