"""Contested matches: where the advice and the environment's reward disagree (issue: verdicts
a researcher can trust)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.conformance import Conformance, compare, reference_agreement
from engine.pipeline import replay_with_teacher, run_tournament
from engine.tournament import ScoreJudge
from engine.treefile import TreeDocument, replay


@pytest.fixture(scope="module")
def standing() -> TreeDocument:
    return run_tournament(env_id="Humanoid-v5", n_candidates=16, p=0.9, seed=0, teacher="standing")


def test_the_good_teacher_keeps_no_contested_match(standing: TreeDocument) -> None:
    good = replay_with_teacher(standing, "good")
    c = compare(standing, good)
    assert c.contested.n > 0
    assert c.contested.kept == 0 and c.contested.agreement == 0.0
    assert all(r.contested for r in c.rejected)  # it overturns exactly the contested ones
    assert c.n_agree == c.n_matches - c.contested.n


def test_the_same_teacher_keeps_every_contested_match(standing: TreeDocument) -> None:
    c = compare(standing, replay_with_teacher(standing, "standing"))
    assert c.contested.n > 0 and c.contested.kept == c.contested.n
    low, high = c.contested.agreement_ci
    assert 0 < low < high == 1.0


def test_contested_means_the_winner_has_the_lower_reward(standing: TreeDocument) -> None:
    reward = {c.id: c.env_reward for c in standing.candidates}
    expected = sum(reward[w] < reward[m.b if w == m.a else m.a] for m, w in standing.matches)
    assert compare(standing, standing).contested.n == expected


def test_reference_agreement_is_what_an_r_only_judge_scores(standing: TreeDocument) -> None:
    r_only = replay(
        standing,
        ScoreJudge({c.id: c.env_reward for c in standing.candidates}),
        "R",
        scores={c.id: c.env_reward for c in standing.candidates},
    )
    assert reference_agreement(standing) == compare(standing, r_only).match_agreement
    assert compare(standing, r_only).contested.kept == 0


def test_advice_that_never_goes_against_the_reward_has_nothing_contested(
    standing: TreeDocument,
) -> None:
    good = replay_with_teacher(standing, "good")
    c = compare(good, replay_with_teacher(standing, "standing"))
    assert c.contested.n == 0 and c.contested.agreement is None
    assert c.contested.agreement_ci is None and c.reference_agreement == 1.0


def test_json_round_trip(standing: TreeDocument) -> None:
    c = compare(standing, replay_with_teacher(standing, "good"))
    obj = c.to_json()
    assert set(obj["contested"]) == {"n", "kept", "agreement", "agreement_ci"}
    assert isinstance(obj["contested"]["agreement_ci"], list)
    assert obj["rejected"][0]["contested"] is True
    assert Conformance.from_json(obj) == c
    assert np.isclose(obj["reference_agreement"], c.reference_agreement)
