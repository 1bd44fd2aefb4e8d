"""The ``acv.tree/1`` document in memory: :class:`TreeDocument`, :func:`make_document`, and
:func:`replay`, its bracket judged again (here, below the agents that replay it)."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from engine.bracket import Bracket, FirstRound, Match
from engine.candidates import Candidate
from engine.preference_tree import PreferenceTree, from_dendrogram
from engine.tournament import Judge, dendrogram, play, tie_heights

SCHEMA = "acv.tree/1"


@dataclass(frozen=True)
class TreeDocument:
    """A complete labelled bracket over a candidate set.

    Attributes:
        env_id: Gymnasium MuJoCo env the states belong to.
        seed: seed the candidates and bracket were drawn with.
        p: Braverman-Mossel coin probability used for seeding.
        judge: who decided the matches (``"standing"``, ``"participant:12"``, ``"agent:..."``).
        r_b: leaf reward constant of T_r.
        r_e: edge reward constant of T_r.
        candidates: the players, ids ``0 .. N-1`` in order.
        first_round: bracket order, ``(a, None)`` for a bye.
        results: ``(round, slot) -> winner`` for every match.
        tree: the Preference Tree built from ``results``.
        scores: the judge's score per candidate, when it judged by a score.
        ties: ``(round, slot)`` of the matches the judge could not tell; ``results`` holds
            the seeded coin's winner there (docs/method.md §2.14).
    """

    env_id: str
    seed: int
    p: float
    judge: str
    r_b: float
    r_e: float
    candidates: list[Candidate]
    first_round: FirstRound
    results: dict[tuple[int, int], int]
    tree: PreferenceTree
    scores: dict[int, float] | None = None
    ties: frozenset[tuple[int, int]] = frozenset()

    @property
    def bracket(self) -> Bracket:
        return Bracket(self.first_round)

    @property
    def matches(self) -> list[tuple[Match, int]]:
        """Every match with its winner, in (round, slot) order."""
        return [(m, self.results[(m.round, m.slot)]) for m in self.bracket.matches(self.results)]

    @property
    def untied_matches(self) -> list[tuple[Match, int]]:
        """The matches the judge decided, leaving out its ties: the only ones with a
        preference, so the only ones agreement and contested matches count."""
        return [(m, w) for m, w in self.matches if not self.tied(m)]

    def tied(self, match: Match) -> bool:
        """Whether the judge could not tell ``match`` (its winner is the seeded coin's)."""
        return (match.round, match.slot) in self.ties

    @property
    def by_id(self) -> dict[int, Candidate]:
        return {c.id: c for c in self.candidates}


def make_document(
    *,
    env_id: str,
    seed: int,
    p: float,
    judge: str,
    candidates: list[Candidate],
    first_round: FirstRound,
    results: dict[tuple[int, int], int],
    r_b: float = 1.0,
    r_e: float = 1.0,
    scores: dict[int, float] | None = None,
    ties: Collection[tuple[int, int]] = frozenset(),
) -> TreeDocument:
    """Build the Preference Tree of a complete bracket and wrap everything in a document.

    Raises:
        InputError: the bracket is incomplete, or a tie names no match of it.
    """
    bracket = Bracket(first_round)
    root = dendrogram(bracket, results)  # first: a tie is checked against complete results
    raised = tie_heights(bracket, results, ties)
    tree = from_dendrogram(root, r_b=r_b, r_e=r_e, raised=raised)
    return TreeDocument(
        env_id,
        seed,
        p,
        judge,
        r_b,
        r_e,
        candidates,
        first_round,
        results,
        tree,
        scores,
        frozenset(ties),
    )


def replay(
    doc: TreeDocument, judge: Judge, judge_name: str, scores: dict[int, float] | None = None
) -> TreeDocument:
    """The same bracket judged by ``judge``: trees over it are comparable."""
    results = play(doc.bracket, doc.by_id, judge)
    return make_document(
        env_id=doc.env_id,
        seed=doc.seed,
        p=doc.p,
        judge=judge_name,
        candidates=doc.candidates,
        first_round=doc.first_round,
        results=results,
        r_b=doc.r_b,
        r_e=doc.r_e,
        scores=scores,
    )
