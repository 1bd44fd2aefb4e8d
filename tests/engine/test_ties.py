"""Ties ("can't tell"), docs/method.md §2.14: F at a tie node, the tree file's ``tie`` flag,
and a tied match counting as neither agreement nor disagreement."""

from __future__ import annotations

import copy
import dataclasses
import json
from typing import Any

import numpy as np
import pytest

from engine.advice import AdviceReward
from engine.bracket import Bracket, FirstRound, make_first_round
from engine.conformance import compare, reference_agreement
from engine.errors import InputError
from engine.preference_tree import from_dendrogram
from engine.tournament import ScoreJudge, dendrogram, match_heights, play
from engine.treefile import (
    TreeDocument,
    dumps,
    make_document,
    replay,
    tree_from_json,
    tree_to_json,
)
from engine.verdict import bracket_pairs
from tests.support.candidates import make_candidates

Results = dict[tuple[int, int], int]
Ties = frozenset[tuple[int, int]]

#: (first round, results, ties, the tied losers' raised heights). Hand-built brackets; the
#: last has two byes meeting in round 2, a match of height 1, not 2.
CASES: list[tuple[FirstRound, Results, Ties, dict[int, int]]] = [
    ([(0, 1)], {(1, 0): 0}, frozenset({(1, 0)}), {1: 1}),
    ([(0, 1), (2, 3)], {(1, 0): 0, (1, 1): 2, (2, 0): 0}, frozenset({(1, 0)}), {1: 1}),
    ([(0, 1), (2, 3)], {(1, 0): 0, (1, 1): 2, (2, 0): 0}, frozenset({(2, 0)}), {2: 2}),
    (
        [(0, 1), (2, 3)],
        {(1, 0): 0, (1, 1): 2, (2, 0): 0},
        frozenset({(1, 1), (2, 0)}),
        {3: 1, 2: 2},
    ),
    (
        [(0, None), (3, 4), (1, None), (2, None)],
        {(1, 1): 3, (2, 0): 0, (2, 1): 1, (3, 0): 1},
        frozenset({(2, 1), (1, 1)}),
        {2: 1, 4: 1},
    ),
]
CONSTANTS = [(1.0, 1.0), (0.5, 2.0)]


def _doc(
    first: FirstRound,
    results: Results,
    ties: Ties = frozenset(),
    *,
    r_b: float = 1.0,
    r_e: float = 1.0,
    scores: dict[int, float] | None = None,
) -> TreeDocument:
    n = len(Bracket(first).players)
    return make_document(
        env_id="Hopper-v5",
        seed=0,
        p=0.9,
        judge="participant:1",
        candidates=make_candidates(n),
        first_round=first,
        results=results,
        r_b=r_b,
        r_e=r_e,
        scores=scores,
        ties=ties,
    )


@pytest.mark.parametrize(("r_b", "r_e"), CONSTANTS)
@pytest.mark.parametrize(("first", "results", "ties", "raised"), CASES)
def test_a_tied_loser_is_rewarded_as_if_it_had_won_the_match(
    first: FirstRound,
    results: Results,
    ties: Ties,
    raised: dict[int, int],
    r_b: float,
    r_e: float,
) -> None:
    doc = _doc(first, results, ties, r_b=r_b, r_e=r_e)
    nodes = doc.tree.nodes
    assert {s: nodes[s].height for s in raised} == raised
    heights = match_heights(Bracket(first))
    for key in ties:  # T_r(L) is what the winner had right after the tied match
        assert raised[_loser(doc, key)] == heights[key]
        assert nodes[_loser(doc, key)].reward == pytest.approx(r_e * heights[key] - r_b)
    for node in nodes.values():  # the paper's identity holds at every node, ties or not
        assert node.reward == pytest.approx(r_e * node.height - r_b)
        assert node.weight is None or node.weight >= 0


@pytest.mark.parametrize(("first", "results", "ties", "raised"), CASES)
def test_a_tie_changes_heights_and_rewards_only_never_the_shape(
    first: FirstRound, results: Results, ties: Ties, raised: dict[int, int]
) -> None:
    tied, plain = _doc(first, results, ties).tree, _doc(first, results).tree
    assert tied.root == plain.root
    assert {s: n.parent for s, n in tied.nodes.items()} == {
        s: n.parent for s, n in plain.nodes.items()
    }
    changed = {s for s in plain.nodes if tied.nodes[s].height != plain.nodes[s].height}
    assert changed == set(raised)


def test_f_at_a_tied_loser_is_its_raised_tree_reward() -> None:
    first, results, ties, raised = CASES[3]
    doc = _doc(first, results, ties, r_e=2.0)
    advice = AdviceReward.from_tree(doc)
    for loser, height in raised.items():  # nearest mode: F at a node's own state is T_r
        f = advice(doc.by_id[loser].qpos[None, :])[0]
        assert f == pytest.approx(2.0 * height - 1.0)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("n", [2, 5, 8, 13])
def test_no_ties_is_the_paper_s_tree(n: int, seed: int) -> None:
    doc = _random_doc(n, seed)
    again = _doc(doc.first_round, doc.results, frozenset(), scores=doc.scores)
    root = dendrogram(doc.bracket, doc.results)
    assert doc.tree == from_dendrogram(root) == from_dendrogram(root, raised={}) == again.tree
    assert all(node.reward == pytest.approx(node.height - 1.0) for node in doc.tree.nodes.values())
    assert all("tie" not in m for m in tree_to_json(doc)["matches"])


@pytest.mark.parametrize("seed", range(4))
def test_random_ties_keep_the_identity_and_round_trip(seed: int) -> None:
    plain = _random_doc(9, seed)
    rng = np.random.default_rng(seed)
    keys = [(m.round, m.slot) for m, _ in plain.matches]
    ties = frozenset(k for k in keys if rng.random() < 0.4)
    doc = _doc(plain.first_round, plain.results, ties)
    assert all(node.reward == pytest.approx(node.height - 1.0) for node in doc.tree.nodes.values())
    text = dumps(doc)
    back = tree_from_json(json.loads(text))
    assert back.ties == ties and back.tree == doc.tree and dumps(back) == text
    flags = {(m["round"], m["a"], m["b"]): m.get("tie") for m in json.loads(text)["matches"]}
    assert sorted(k for k, v in flags.items() if v) == sorted(
        (m.round, m.a, m.b) for m, _ in doc.matches if doc.tied(m)
    )
    assert set(flags.values()) <= {True, None}  # true when tied, else absent


def _with_tie(obj: dict[str, Any], value: Any, index: int = 0) -> None:
    obj["matches"][index]["tie"] = value


@pytest.mark.parametrize(
    ("tamper", "words"),
    [
        (lambda o: _with_tie(o, 1), "'tie' must be true or false"),
        (lambda o: _with_tie(o, "true"), "'tie' must be true or false"),
        (lambda o: _with_tie(o, None), "'tie' must be true or false"),
        (lambda o: _with_tie(o, [True]), "'tie' must be true or false"),
        (lambda o: _with_tie(o, True), "does not match"),  # the stored tree has no tie
        (
            lambda o: o["matches"].append({"round": 1, "a": 0, "b": 2, "winner": 0, "tie": True}),
            "not in the bracket",
        ),
    ],
    ids=["int", "text", "null", "list", "tree-disagrees", "unknown-match"],
)
def test_bad_tie_json_is_an_input_error(tamper, words: str) -> None:
    first, results, _, _ = CASES[1]
    obj = copy.deepcopy(tree_to_json(_doc(first, results)))
    tamper(obj)
    with pytest.raises(InputError) as info:
        tree_from_json(obj)
    assert words in str(info.value)


def test_a_false_tie_flag_reads_as_no_tie() -> None:
    first, results, _, _ = CASES[1]
    obj = tree_to_json(_doc(first, results))
    _with_tie(obj, False)
    assert tree_from_json(obj).ties == frozenset()


@pytest.mark.parametrize(
    "ties",
    [frozenset({(4, 0)}), frozenset({(1, 0)}), frozenset({(2, 5)})],
    ids=["no-such-round", "bye", "no-such-slot"],
)
def test_a_tie_on_no_match_is_an_input_error(ties: Ties) -> None:
    first, results, _, _ = CASES[4]  # slot (1, 0) is player 0's bye
    with pytest.raises(InputError, match="not a decided match"):
        _doc(first, results, ties)


#: 4 players, candidate i has R = i; the human picks 0 over 1 in the tied first match,
#: against R (so contested were it advice).
FIRST: FirstRound = [(0, 1), (2, 3)]
HUMAN: Results = {(1, 0): 0, (1, 1): 3, (2, 0): 3}


def _human(ties: Ties) -> TreeDocument:
    doc = _doc(FIRST, HUMAN, ties)
    cands = [dataclasses.replace(c, env_reward=float(c.id)) for c in doc.candidates]
    return dataclasses.replace(doc, candidates=cands)


@pytest.mark.parametrize("agent_winner", [0, 1], ids=["agrees", "disagrees"])
def test_a_tied_match_is_neither_agreement_nor_disagreement(agent_winner: int) -> None:
    human = _human(frozenset({(1, 0)}))
    scores = {0: 0.0, 1: 0.0, 2: 1.0, 3: 5.0}
    scores[agent_winner] = 2.0
    agent = replay(human, ScoreJudge(scores), "agent", scores=scores)
    tied, plain = compare(human, agent), compare(_human(frozenset()), agent)
    assert (plain.n_matches, tied.n_matches) == (3, 2)
    assert tied.n_agree == plain.n_agree - (agent_winner == 0) == 2
    assert tied.match_agreement == 1.0
    assert all((r.a, r.b) != (0, 1) for r in tied.rejected)
    assert (plain.contested.n, tied.contested.n) == (1, 0)  # 0 over 1 goes against R
    assert (plain.reference_agreement, tied.reference_agreement) == (2 / 3, 1.0)
    assert reference_agreement(human) == 1.0


def test_the_verdict_leaves_tied_matches_out() -> None:
    assert bracket_pairs(_human(frozenset())) == ((0, 1, 0), (2, 3, 3), (0, 3, 3))
    assert bracket_pairs(_human(frozenset({(1, 0), (2, 0)}))) == ((2, 3, 3),)


def test_a_tree_of_ties_only_has_no_advice_to_compare() -> None:
    human = _human(frozenset({(1, 0), (1, 1), (2, 0)}))
    with pytest.raises(InputError, match="every match of the human's tree is a tie"):
        compare(human, human)


def test_a_tie_in_the_agent_s_tree_is_no_preference() -> None:
    human, other = _human(frozenset()), _human(frozenset({(1, 0)}))
    result = compare(human, other)  # the same picks, but the other could not tell 0 from 1
    assert (result.n_agree, result.n_matches) == (2, 3)
    assert [(r.a, r.b, r.agent_winner) for r in result.rejected] == [(0, 1, None)]


def _loser(doc: TreeDocument, key: tuple[int, int]) -> int:
    match = next(m for m, _ in doc.matches if (m.round, m.slot) == key)
    return match.b if doc.results[key] == match.a else match.a


def _random_doc(n: int, seed: int) -> TreeDocument:
    """A complete bracket over ``n`` random candidates, judged by random scores."""
    rng = np.random.default_rng(seed)
    cands = make_candidates(n, rng)
    first = make_first_round(list(range(n)), np.array([c.env_reward for c in cands]), 0.5, rng)
    scores = {c.id: float(rng.normal()) for c in cands}
    results = play(Bracket(first), {c.id: c for c in cands}, ScoreJudge(scores))
    return _doc(first, results, scores=scores)
