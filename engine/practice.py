"""Practice pairs before the bracket (issue 28 §3): how many, which states, which pairs.

A study may ask each participant 2 to 5 practice pairs before their bracket, to learn how
choosing works. Practice must not prime the bracket, so its states are never the study's
candidates: they are sampled like candidates (uniformly from random rollouts) but from a
generator stream of their own (:func:`practice_rng`), and any state equal to a candidate is
dropped. A study has ``2 k`` practice states for ``k`` pairs.

Each participant gets the pairs in their own deterministic order (:func:`practice_plan`,
seeded by the study's seed and the participant's id): about half are *instructed* pairs
("choose the picture with the marker": one state is shown with a marker,
:func:`engine.render.image.with_marker`), whose answer is right or wrong; the others are
plain preference pairs, which have no right answer. Nothing of practice is stored.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from engine.candidates import Candidate, sample_candidates
from engine.errors import InputError

MIN_PRACTICE_PAIRS = 2
MAX_PRACTICE_PAIRS = 5
#: Entropy word of practice's generator streams ("prac"), so that they never replay the
#: candidates' stream (``default_rng(seed)``).
_STREAM = 0x70726163
#: States sampled beyond the ``2 k`` needed, to replace any that equals a candidate.
_SPARE = 4

PairKind = Literal["instructed", "preference"]
Side = Literal["left", "right"]
SIDES: tuple[Side, Side] = ("left", "right")


def practice_pairs_error(n: int) -> str | None:
    """Why ``n`` practice pairs cannot be asked, or None (0, or 2 to 5)."""
    if n == 0 or MIN_PRACTICE_PAIRS <= n <= MAX_PRACTICE_PAIRS:
        return None
    return (
        f"practice_pairs must be 0 (no practice) or {MIN_PRACTICE_PAIRS} to "
        f"{MAX_PRACTICE_PAIRS}, got {n}"
    )


def check_practice_pairs(n: int) -> int:
    """Return ``n`` if it is a valid number of practice pairs; else :class:`InputError`."""
    if (message := practice_pairs_error(n)) is not None:
        raise InputError(message)
    return n


def practice_rng(seed: int, *keys: int) -> np.random.Generator:
    """A generator for practice, apart from the candidates' ``default_rng(seed)``."""
    return np.random.default_rng([_STREAM, seed, *keys])


def sample_practice_states(
    env_id: str, n_pairs: int, *, seed: int, exclude: Sequence[np.ndarray] = ()
) -> list[Candidate]:
    """The ``2 n_pairs`` practice states of a study, ids ``0 .. 2 n_pairs - 1``.

    Args:
        env_id: the study's Gymnasium MuJoCo env id.
        n_pairs: the study's practice pairs, 2 to 5.
        seed: the study's seed (the candidates' seed; practice draws another stream).
        exclude: the candidates' ``qpos``: no practice state equals one.

    Raises:
        InputError: ``n_pairs`` is not 2 to 5, or the env is unknown.
        RuntimeError: fewer than ``2 n_pairs`` states differ from the candidates (never seen:
            states of independent random rollouts do not repeat).
    """
    if n_pairs == 0:
        raise InputError("a study without practice pairs has no practice states")
    check_practice_pairs(n_pairs)
    needed = 2 * n_pairs
    drawn = sample_candidates(env_id, needed + _SPARE, rng=practice_rng(seed), mode="uniform")
    kept = [c for c in drawn if not any(np.array_equal(c.qpos, q) for q in exclude)][:needed]
    if len(kept) < needed:
        raise RuntimeError("too few practice states differ from the candidates")
    return [replace(c, id=i) for i, c in enumerate(kept)]


@dataclass(frozen=True)
class PracticePair:
    """One practice pair as a participant sees it.

    Attributes:
        position: its place in the participant's practice, from 0.
        kind: ``instructed`` (one picture has the marker) or ``preference``.
        left: the practice state shown on the left (an index of the study's states).
        right: the practice state shown on the right.
        marked: the side whose picture has the marker (instructed pairs), else None.
    """

    position: int
    kind: PairKind
    left: int
    right: int
    marked: Side | None

    def is_marked(self, side: Side) -> bool:
        """Whether the picture on ``side`` is shown with the marker."""
        return self.marked == side

    def correct(self, side: Side) -> bool | None:
        """Whether choosing ``side`` is right (None: a preference pair has no right answer)."""
        return None if self.marked is None else side == self.marked


def practice_plan(n_pairs: int, *, seed: int, participant_id: int) -> list[PracticePair]:
    """A participant's practice pairs, in order: ``ceil(n_pairs / 2)`` instructed pairs mixed
    among the preference pairs, each of the ``2 n_pairs`` states shown once, sides and markers
    drawn from a generator seeded by the study's seed and the participant's id.
    """
    check_practice_pairs(n_pairs)
    rng = practice_rng(seed, participant_id)
    instructed = (n_pairs + 1) // 2
    kinds = rng.permutation([True] * instructed + [False] * (n_pairs - instructed))
    states = rng.permutation(2 * n_pairs)
    marks = rng.integers(2, size=n_pairs)
    return [
        PracticePair(
            position=k,
            kind="instructed" if kinds[k] else "preference",
            left=int(states[2 * k]),
            right=int(states[2 * k + 1]),
            marked=SIDES[int(marks[k])] if kinds[k] else None,
        )
        for k in range(n_pairs)
    ]
