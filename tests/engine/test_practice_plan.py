"""Practice pairs (issue 28 §3): the allowed counts, states apart from the candidates, and
each participant's seeded mix of instructed and preference pairs."""

from __future__ import annotations

import numpy as np
import pytest

from engine.candidates import sample_candidates
from engine.errors import InputError
from engine.practice import (
    check_practice_pairs,
    practice_pairs_error,
    practice_plan,
    sample_practice_states,
)


@pytest.mark.parametrize("n", [0, 2, 3, 4, 5])
def test_allowed_counts(n: int) -> None:
    assert check_practice_pairs(n) == n and practice_pairs_error(n) is None


@pytest.mark.parametrize("n", [-1, 1, 6, 100])
def test_refused_counts_say_what_is_allowed(n: int) -> None:
    with pytest.raises(
        InputError, match=rf"practice_pairs must be 0 \(no practice\) or 2 to 5, got {n}"
    ):
        check_practice_pairs(n)


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_plan_mixes_kinds_and_shows_each_state_once(n: int) -> None:
    plan = practice_plan(n, seed=7, participant_id=3)
    assert [p.position for p in plan] == list(range(n))
    instructed = [p for p in plan if p.kind == "instructed"]
    assert len(instructed) == (n + 1) // 2
    assert all(p.marked in ("left", "right") for p in instructed)
    assert all(p.marked is None for p in plan if p.kind == "preference")
    assert sorted(s for p in plan for s in (p.left, p.right)) == list(range(2 * n))


def test_plan_is_seeded_by_study_and_participant() -> None:
    plan = practice_plan(5, seed=7, participant_id=3)
    assert plan == practice_plan(5, seed=7, participant_id=3)
    others = [practice_plan(5, seed=s, participant_id=p) for s, p in ((8, 3), (7, 4), (7, 5))]
    assert all(other != plan for other in others)


def test_feedback_of_each_kind() -> None:
    plan = practice_plan(3, seed=1, participant_id=1)
    for pair in plan:
        if pair.marked is None:
            assert pair.correct("left") is None and pair.correct("right") is None
        else:
            other = "left" if pair.marked == "right" else "right"
            assert pair.correct(pair.marked) is True and pair.correct(other) is False
            assert pair.is_marked(pair.marked) and not pair.is_marked(other)


def test_practice_states_are_not_the_candidates() -> None:
    seed = 5
    candidates = sample_candidates("Hopper-v5", 8, rng=np.random.default_rng(seed))
    states = sample_practice_states("Hopper-v5", 3, seed=seed, exclude=[c.qpos for c in candidates])
    assert [s.id for s in states] == list(range(6))
    assert not any(np.array_equal(s.qpos, c.qpos) for s in states for c in candidates)
    again = sample_practice_states("Hopper-v5", 3, seed=seed)
    assert all(np.array_equal(a.qpos, b.qpos) for a, b in zip(states, again, strict=True))


def test_a_state_equal_to_a_candidate_is_replaced() -> None:
    drawn = sample_practice_states("Hopper-v5", 2, seed=0)
    kept = sample_practice_states("Hopper-v5", 2, seed=0, exclude=[drawn[1].qpos])
    assert len(kept) == 4 and not any(np.array_equal(s.qpos, drawn[1].qpos) for s in kept)
    assert np.array_equal(kept[0].qpos, drawn[0].qpos) and np.array_equal(
        kept[1].qpos, drawn[2].qpos
    )


@pytest.mark.parametrize("n", [0, 1, 6])
def test_no_states_for_a_count_out_of_range(n: int) -> None:
    with pytest.raises(InputError):
        sample_practice_states("Hopper-v5", n, seed=0)
