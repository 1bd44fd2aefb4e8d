"""Shared engine fixtures: small candidate sets built by hand (no env needed)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.candidates import Candidate


def make_candidates(n: int, rng: np.random.Generator | None = None) -> list[Candidate]:
    """``n`` candidates with distinct random rewards and 3-dim states."""
    rng = rng or np.random.default_rng(0)
    rewards = rng.permutation(n).astype(float)
    return [
        Candidate(i, rng.normal(size=5), rng.normal(size=4), float(rewards[i])) for i in range(n)
    ]


@pytest.fixture
def candidates16() -> list[Candidate]:
    return make_candidates(16)
