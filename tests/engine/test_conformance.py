"""Conformance metrics between two trees over one bracket."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.bracket import Bracket, make_first_round
from engine.conformance import compare, tree_edit_distance
from engine.errors import InputError
from engine.pipeline import replay
from engine.tournament import ScoreJudge, play
from engine.treefile import TreeDocument, make_document
from tests.engine.conftest import make_candidates


def _doc(n: int = 16, seed: int = 0) -> TreeDocument:
    rng = np.random.default_rng(seed)
    cands = make_candidates(n, rng)
    scores = {c.id: c.env_reward for c in cands}
    first = make_first_round(list(range(n)), np.array(list(scores.values())), 0.9, rng)
    results = play(Bracket(first), {c.id: c for c in cands}, ScoreJudge(scores))
    return make_document(
        env_id="Hopper-v5",
        seed=seed,
        p=0.9,
        judge="good",
        candidates=cands,
        first_round=first,
        results=results,
        scores=scores,
    )


def test_reversed_judge_rejects_every_first_round_match() -> None:
    human = _doc()
    agent = replay(
        human,
        ScoreJudge({c.id: -c.env_reward for c in human.candidates}),
        "bad",
        scores={c.id: -c.env_reward for c in human.candidates},
    )
    result = compare(human, agent)
    assert result.match_agreement == 0.0
    assert len(result.rejected) == 15
    assert result.kendall_tau_b < 0
    assert not result.same_champion
    assert 0 < result.tree_edit_distance <= 1
    lo, hi = result.match_agreement_ci
    assert lo == 0.0 and 0 < hi < 0.3


def test_one_flipped_first_round_match_is_listed() -> None:
    human = _doc()
    m, winner = human.matches[0]
    loser = m.b if winner == m.a else m.a
    scores = {c.id: c.env_reward for c in human.candidates}
    scores[loser] = scores[winner] + 0.5  # loser now beats its first opponent only
    result = compare(human, replay(human, ScoreJudge(scores), "agent", scores=scores))
    assert [(r.round, r.human_winner, r.agent_winner) for r in result.rejected][0] == (
        1,
        winner,
        loser,
    )
    assert result.n_agree == result.n_matches - len(result.rejected)


def test_trees_over_different_brackets_are_rejected() -> None:
    with pytest.raises(InputError):
        compare(_doc(seed=0), _doc(seed=1))
    other = dataclasses.replace(_doc(), env_id="Humanoid-v5")
    with pytest.raises(InputError):
        compare(_doc(), other)


def test_edit_distance_is_normalised_to_unit_interval() -> None:
    human = _doc(8)
    assert tree_edit_distance(human.tree, human.tree) == 0.0
    flipped = replay(human, ScoreJudge({c.id: -c.env_reward for c in human.candidates}), "x")
    assert 0 < tree_edit_distance(human.tree, flipped.tree) <= 1
