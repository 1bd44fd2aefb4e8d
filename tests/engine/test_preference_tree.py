"""Tournament play, dendrogram and Preference Tree (Algorithm 1), with property tests."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.bracket import Bracket, make_first_round
from engine.conformance import compare
from engine.errors import InputError
from engine.preference_tree import from_dendrogram
from engine.teachers import CoinJudge
from engine.tournament import ScoreJudge, dendrogram, play
from engine.treefile import make_document, replay
from tests.support.candidates import make_candidates


def test_paper_figure2_shape_six_players_with_byes() -> None:
    """s1 and s4 get byes; s2-s3 and s5-s6 play; the higher id wins every match.

    Dendrogram: s6 beats s5 (h1); s3 beats s2 (h1); s4 (bye) beats s3 (h2); s6 beats s1
    (bye, h2); s6 beats s4 in the final (h3). Preference Tree: s6 -> {s4 -> s3 -> s2,
    s5, s1}.
    """
    cands = {c.id: c for c in make_candidates(7)}
    first = [(1, None), (6, 5), (4, None), (3, 2)]
    results = play(Bracket(first), cands, ScoreJudge({i: i for i in range(7)}))
    tree = from_dendrogram(dendrogram(Bracket(first), results), r_b=1.0, r_e=2.0)
    assert tree.root == 6
    parents = {s: n.parent for s, n in tree.nodes.items()}
    assert parents == {6: None, 4: 6, 3: 4, 2: 3, 5: 6, 1: 6}
    heights = {s: n.height for s, n in tree.nodes.items()}
    assert heights == {6: 3, 4: 2, 3: 1, 2: 0, 5: 0, 1: 0}
    assert tree.nodes[6].children == (4, 1, 5)  # latest round first, then by id
    assert {s: n.weight for s, n in tree.nodes.items()} == {6: None, 4: 1, 3: 1, 2: 1, 5: 3, 1: 3}
    assert {s: n.depth for s, n in tree.nodes.items()} == {6: 1, 4: 2, 3: 3, 2: 4, 5: 2, 1: 2}
    # Eq. 1 by hand: T(2)=T(5)=T(1)=-1; T(3)=-1+2*1=1; T(4)=1+2=3; T(6)=mean(3+2, -1+6, -1+6)=5
    assert tree.nodes[6].reward == pytest.approx(5.0)
    assert tree.nodes[4].reward == pytest.approx(3.0)


def test_incomplete_bracket_has_no_dendrogram() -> None:
    with pytest.raises(InputError):
        dendrogram(Bracket([(0, 1), (2, 3)]), {(1, 0): 0})


def test_judge_returning_a_stranger_is_rejected() -> None:
    cands = {c.id: c for c in make_candidates(2)}
    with pytest.raises(InputError):
        play(Bracket([(0, 1)]), cands, lambda a, b: 7)


brackets = st.tuples(
    st.integers(2, 64),
    st.integers(0, 2**32 - 1),
    st.floats(0.0, 1.0),
    st.booleans(),
    st.floats(0.1, 5.0),
    st.floats(0.1, 5.0),
)


@settings(max_examples=60, deadline=None)
@given(brackets)
def test_preference_tree_properties(params) -> None:
    n, seed, p, coin, r_b, r_e = params
    rng = np.random.default_rng(seed)
    cands = make_candidates(n, rng)
    abilities = np.array([c.env_reward for c in cands])
    first = make_first_round([c.id for c in cands], abilities, p, rng)
    judge = CoinJudge(rng) if coin else ScoreJudge({c.id: rng.normal() for c in cands})
    results = play(Bracket(first), {c.id: c for c in cands}, judge)
    doc = make_document(
        env_id="Hopper-v5",
        seed=seed,
        p=p,
        judge="x",
        candidates=cands,
        first_round=first,
        results=results,
        r_b=r_b,
        r_e=r_e,
    )
    tree = doc.tree
    assert sorted(tree.nodes) == list(range(n))
    final = max(results)
    assert tree.root == results[final]
    won = {(w, m.b if w == m.a else m.a) for m, w in doc.matches}
    for s, node in tree.nodes.items():
        assert node.reward == pytest.approx(r_e * node.height - r_b)
        if node.parent is None:
            assert (s, node.depth, node.weight) == (tree.root, 1, None)
            continue
        parent = tree.nodes[node.parent]
        assert (node.parent, s) in won
        assert node.weight == parent.height - node.height > 0
        assert node.depth == parent.depth + 1
        assert s in parent.children


@settings(max_examples=25, deadline=None)
@given(st.integers(2, 64), st.integers(0, 2**32 - 1))
def test_replay_with_same_judge_agrees_fully(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    cands = make_candidates(n, rng)
    scores = {c.id: float(rng.normal()) for c in cands}
    first = make_first_round(list(range(n)), np.array([c.env_reward for c in cands]), 0.9, rng)
    results = play(Bracket(first), {c.id: c for c in cands}, ScoreJudge(scores))
    doc = make_document(
        env_id="Hopper-v5",
        seed=seed,
        p=0.9,
        judge="a",
        candidates=cands,
        first_round=first,
        results=results,
    )
    again = compare(doc, replay(doc, ScoreJudge(scores), "b"))
    assert again.match_agreement == 1.0
    assert again.tree_edit_distance == 0.0
    assert again.same_champion and not again.rejected
