"""Playing a bracket with a judge, and the tournament dendrogram.

A *judge* decides each match: a person (through the web app), a simulated teacher, or the
agent's shaped reward. The dendrogram is a binary tree whose leaves are the candidates (height
0); a match node holds its winner and has height ``1 + max(children's heights)``. A bye passes
the player's node up unchanged.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Protocol

from engine.bracket import Bracket, Match, Results
from engine.candidates import Candidate
from engine.errors import InputError


class Judge(Protocol):
    """Decides a match between two candidates."""

    def __call__(self, a: Candidate, b: Candidate) -> int:
        """Return the id of the preferred candidate (``a.id`` or ``b.id``)."""
        ...


def score_winner(scores: Mapping[int, float], a: int, b: int) -> int | None:
    """The one tie rule of every score-based judgement: of ``a`` and ``b``, the id with the
    strictly higher score; None on a tie (the scores express no preference).

    Conformance's reference (the R-only judge) and contested matches, and :class:`ScoreJudge`
    all decide by it, so a tie means the same everywhere: no preference, which agrees with
    neither side. Only where a bracket must go on does :class:`ScoreJudge` then advance ``a``.
    """
    if scores[a] == scores[b]:
        return None
    return a if scores[a] > scores[b] else b


class ScoreJudge:
    """Prefers the candidate with the higher score (:func:`score_winner`); a tie has no
    preference, and the bracket advances ``a``, the higher seed's side.

    Args:
        scores: candidate id -> score (for example R(s), or the agent's shaped reward).
    """

    def __init__(self, scores: Mapping[int, float]):
        self.scores = {int(k): float(v) for k, v in scores.items()}

    def __call__(self, a: Candidate, b: Candidate) -> int:
        winner = score_winner(self.scores, a.id, b.id)
        return a.id if winner is None else winner


def play(
    bracket: Bracket,
    candidates: Mapping[int, Candidate],
    judge: Judge,
    results: Results | None = None,
) -> dict[tuple[int, int], int]:
    """Play every open match, round by round, until the bracket is complete.

    Args:
        bracket: the bracket's structure.
        candidates: id -> candidate, covering the bracket's players.
        judge: decides each match.
        results: matches already decided (kept as they are).

    Returns:
        ``(round, slot) -> winner id`` for every match.
    """
    decided = dict(results or {})
    while open_ := bracket.open_matches(decided):
        for m in open_:
            winner = judge(candidates[m.a], candidates[m.b])
            bracket.check_result(m, winner)
            decided[(m.round, m.slot)] = winner
    return decided


@dataclass(frozen=True)
class DendroNode:
    """A dendrogram node: ``value`` is the state it stands for (the winner, for a match)."""

    value: int
    height: int
    children: tuple[DendroNode, ...] = ()


def dendrogram(bracket: Bracket, results: Results) -> DendroNode:
    """Build the dendrogram of a complete bracket."""
    if not bracket.is_complete(results):
        raise InputError("the bracket is not complete: every match needs a winner")
    nodes = [
        DendroNode(a, 0)
        if b is None
        else _match_node(results[(1, k)], DendroNode(a, 0), DendroNode(b, 0))
        for k, (a, b) in enumerate(bracket.first_round)
    ]
    for rnd in range(2, bracket.n_rounds + 1):
        nodes = [
            _match_node(results[(rnd, k)], nodes[2 * k], nodes[2 * k + 1])
            for k in range(len(nodes) // 2)
        ]
    return nodes[0]


def _match_node(winner: int, left: DendroNode, right: DendroNode) -> DendroNode:
    return DendroNode(winner, 1 + max(left.height, right.height), (left, right))


def match_heights(bracket: Bracket) -> dict[tuple[int, int], int]:
    """``(round, slot) -> height`` of every match's dendrogram node.

    A node's height is ``1 + max(children's heights)`` and a bye passes height 0 up, so the
    heights depend on the bracket's shape alone, not on who won (a round-2 match between two
    bye players has height 1, not 2).
    """
    heights = [0 if b is None else 1 for _, b in bracket.first_round]
    out = {(1, k): 1 for k, (_, b) in enumerate(bracket.first_round) if b is not None}
    for rnd in range(2, bracket.n_rounds + 1):
        heights = [1 + max(heights[2 * k], heights[2 * k + 1]) for k in range(len(heights) // 2)]
        out.update({(rnd, k): h for k, h in enumerate(heights)})
    return out


def tie_heights(
    bracket: Bracket, results: Results, ties: Collection[tuple[int, int]]
) -> dict[int, int]:
    """The coin's loser of each tied match -> the height of that match's dendrogram node.

    A tied match is one the judge could not tell; ``results`` holds the seeded coin's winner
    there. Its loser is raised to the height its winner had right after the match
    (docs/method.md §2.14). A player loses once, so each loser appears at most once.

    Raises:
        InputError: a tie on a ``(round, slot)`` that is not a decided match of the bracket.
    """
    matches = {
        (m.round, m.slot): m for m in bracket.matches(results) if (m.round, m.slot) in results
    }
    if unknown := sorted(set(ties) - matches.keys()):
        raise InputError(f"tie on (round, slot) {unknown[0]}, which is not a decided match")
    heights = match_heights(bracket)
    return {_loser(matches[key], results[key]): heights[key] for key in ties}


def _loser(match: Match, winner: int) -> int:
    return match.b if winner == match.a else match.a
