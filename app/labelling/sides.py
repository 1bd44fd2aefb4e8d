"""Seeded coins of a match: which candidate is shown on the left (issue 14: position bias),
and which advances when the participant cannot tell (issue 28 §3)."""

from __future__ import annotations

import hashlib


def _coin(key: str) -> bool:
    """A fair coin derived by hashing ``key`` (no generator state to keep or replay, so any
    process computes the same toss without a query)."""
    return hashlib.blake2b(key.encode(), digest_size=1).digest()[0] & 1 == 1


def a_on_left(*, seed: int, participant_id: int, rnd: int, slot: int) -> bool:
    """Whether a match shows its ``a`` candidate on the left: a fair coin per study seed,
    participant and match."""
    return _coin(f"{seed}:{participant_id}:{rnd}:{slot}")


def a_wins_tie(*, seed: int, participant_id: int, rnd: int, slot: int) -> bool:
    """Whether ``a`` advances from a match the participant could not tell: a fair coin per
    study seed, participant and match, independent of the side coin. Not the Braverman-Mossel
    seeding, which ranks by R and would leak the env reward into the human's tree."""
    return _coin(f"tie:{seed}:{participant_id}:{rnd}:{slot}")
