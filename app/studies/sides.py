"""Which candidate of a match is shown on the left (issue 14: position bias)."""

from __future__ import annotations

import hashlib


def a_on_left(*, seed: int, participant_id: int, rnd: int, slot: int) -> bool:
    """Whether a match shows its ``a`` candidate on the left: a fair coin per study seed,
    participant and match, derived by hashing (no generator state to keep or replay, so
    any process computes the same side without a query)."""
    key = f"{seed}:{participant_id}:{rnd}:{slot}".encode()
    return hashlib.blake2b(key, digest_size=1).digest()[0] & 1 == 1
