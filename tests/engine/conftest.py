"""Shared engine fixtures: small candidate sets built by hand (no env needed)."""

from __future__ import annotations

import pytest

from engine.candidates import Candidate
from tests.support.candidates import make_candidates


@pytest.fixture
def candidates16() -> list[Candidate]:
    return make_candidates(16)
