"""Conformance metrics between two trees over one bracket."""

from __future__ import annotations

import dataclasses

import pytest

from engine.conformance import (
    compare,
    contested_match,
    reference_agreement,
    stored_reward,
    tree_edit_distance,
)
from engine.errors import InputError
from engine.tournament import ScoreJudge, score_winner
from engine.treefile import replay
from tests.support.candidates import r_judged_doc


def test_reversed_judge_rejects_every_first_round_match() -> None:
    human = r_judged_doc()
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
    human = r_judged_doc()
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
        compare(r_judged_doc(seed=0), r_judged_doc(seed=1))
    other = dataclasses.replace(r_judged_doc(), env_id="Humanoid-v5")
    with pytest.raises(InputError):
        compare(r_judged_doc(), other)


def test_edit_distance_is_normalised_to_unit_interval() -> None:
    human = r_judged_doc(8)
    assert tree_edit_distance(human.tree, human.tree) == 0.0
    flipped = replay(human, ScoreJudge({c.id: -c.env_reward for c in human.candidates}), "x")
    assert 0 < tree_edit_distance(human.tree, flipped.tree) <= 1


def test_contested_and_reference_follow_the_r_map_passed_in() -> None:
    human = r_judged_doc()  # judged by the stored R: nothing contested, reference agreement 1
    assert compare(human, human).contested.n == 0 and reference_agreement(human) == 1.0
    flipped = {c.id: -c.env_reward for c in human.candidates}
    c = compare(human, human, flipped)
    assert c.contested.n == c.n_matches and c.reference_agreement == 0.0
    assert reference_agreement(human, flipped) == 0.0


def test_a_tie_in_r_is_neither_contested_nor_an_r_agreement() -> None:
    human = r_judged_doc()
    m, winner = human.matches[0]
    reward = stored_reward(human)
    loser = m.b if winner == m.a else m.a
    reward[loser] = reward[winner]  # R has no preference in this match (the loser plays no other)
    assert score_winner(reward, m.a, m.b) is None
    assert not contested_match(reward, m.a, m.b, winner)
    c = compare(human, human, reward)
    assert c.contested.n == 0
    assert c.reference_agreement == (c.n_matches - 1) / c.n_matches
