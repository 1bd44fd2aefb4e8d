"""The ``acv.tree/1`` document: one labelled bracket and its Preference Tree.

The same JSON is the CLI's file format and the REST API's body (README "Tree file format").
The matches are the source of truth: loading rebuilds the tree from them and rejects a file
whose stored tree disagrees, so a hand-edited or truncated file cannot pass as valid.

A match the judge could not tell carries ``"tie": true`` (its ``winner`` is the seeded coin's);
the key is absent on every other match, so documents without ties are unchanged
(docs/method.md §2.14).
"""

from __future__ import annotations

import json
import math
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.bracket import Bracket, FirstRound, Match
from engine.candidates import Candidate
from engine.errors import InputError, check_seed
from engine.preference_tree import PreferenceTree, from_dendrogram
from engine.tournament import dendrogram, tie_heights

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


def tree_to_json(doc: TreeDocument) -> dict[str, Any]:
    """The document as JSON-ready data (floats kept exact: JSON round-trips ``repr``)."""
    return {
        "schema": SCHEMA,
        "env_id": doc.env_id,
        "seed": doc.seed,
        "p": doc.p,
        "judge": doc.judge,
        "tree_reward": {"r_b": doc.r_b, "r_e": doc.r_e},
        "candidates": [_candidate_json(c, doc.scores) for c in doc.candidates],
        "first_round": [[a, b] for a, b in doc.first_round],
        "matches": [_match_json(doc, m, w) for m, w in doc.matches],
        "tree": {
            "root": doc.tree.root,
            "nodes": [
                {
                    "state": n.state,
                    "parent": n.parent,
                    "height": n.height,
                    "depth": n.depth,
                    "weight": n.weight,
                    "reward": n.reward,
                }
                for n in doc.tree.nodes.values()
            ],
        },
    }


def _match_json(doc: TreeDocument, m: Match, winner: int) -> dict[str, Any]:
    out: dict[str, Any] = {"round": m.round, "a": m.a, "b": m.b, "winner": winner}
    if doc.tied(m):  # only when tied: documents without ties keep their bytes
        out["tie"] = True
    return out


def _candidate_json(c: Candidate, scores: dict[int, float] | None) -> dict[str, Any]:
    out = {"id": c.id, "qpos": c.qpos.tolist(), "qvel": c.qvel.tolist(), "env_reward": c.env_reward}
    if scores is not None:
        out["score"] = scores[c.id]
    return out


def dumps(doc: TreeDocument) -> str:
    """Serialise deterministically: the same document gives the same bytes."""
    return json.dumps(tree_to_json(doc), indent=1) + "\n"


def dump_tree(doc: TreeDocument, path: str | Path) -> None:
    Path(path).write_text(dumps(doc))


def load_tree(path: str | Path) -> TreeDocument:
    """Read and validate an ``acv.tree/1`` file; :class:`InputError` on anything else."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read tree file {path}: {exc}") from exc
    try:
        return tree_from_json(json.loads(text))
    except (json.JSONDecodeError, RecursionError) as exc:
        raise InputError(f"{path} is not an {SCHEMA} document: invalid JSON ({exc})") from exc
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from exc


def tree_from_json(obj: Any) -> TreeDocument:
    """Validate parsed JSON and rebuild the document; :class:`InputError` if invalid."""
    if not isinstance(obj, dict) or obj.get("schema") != SCHEMA:
        raise InputError(f"not an {SCHEMA} document (missing or wrong 'schema')")
    try:
        doc = _parse(obj)
        _check_tree(doc, obj["tree"])
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"malformed {SCHEMA} document: missing key {exc}") from exc
    except (TypeError, ValueError, IndexError, AttributeError, OverflowError) as exc:
        # a value of the wrong type or shape somewhere (a list as an id, text as a reward, ...)
        raise InputError(f"malformed {SCHEMA} document: {type(exc).__name__}: {exc}") from exc
    return doc


def _parse(obj: dict[str, Any]) -> TreeDocument:
    cands, scores = _candidates(obj["candidates"])
    first_round = [(int(a), None if b is None else int(b)) for a, b in obj["first_round"]]
    bracket = Bracket(first_round)
    if sorted(bracket.players) != list(range(len(cands))):
        raise InputError("first round must hold every candidate exactly once")
    results, ties = _results(bracket, obj["matches"])
    tr = obj["tree_reward"]
    return make_document(
        env_id=str(obj["env_id"]),
        seed=check_seed(int(obj["seed"])),
        p=_probability(obj["p"]),
        judge=str(obj["judge"]),
        candidates=cands,
        first_round=first_round,
        results=results,
        r_b=_finite(tr["r_b"], "tree_reward.r_b"),
        r_e=_finite(tr["r_e"], "tree_reward.r_e"),
        scores=scores,
        ties=ties,
    )


def _candidates(items: list[dict[str, Any]]) -> tuple[list[Candidate], dict[int, float] | None]:
    """The candidates, and their judge scores when every one has a ``score``."""
    cands = [
        Candidate(
            int(c["id"]),
            _floats(c["qpos"]),
            _floats(c["qvel"]),
            _finite(c["env_reward"], "env_reward"),
        )
        for c in items
    ]
    if len(cands) < 2:  # one player means no match: nothing to compare or train on
        raise InputError(f"a tree needs at least 2 candidates, got {len(cands)}")
    if [c.id for c in cands] != list(range(len(cands))):
        raise InputError("candidate ids must be 0 .. N-1 in order")
    scores = (
        {c.id: _finite(item["score"], "score") for c, item in zip(cands, items, strict=True)}
        if all("score" in item for item in items)
        else None
    )
    return cands, scores


def _finite(value: Any, name: str) -> float:
    """``value`` as a float; :class:`InputError` if it is NaN or infinite (``1e999`` parses as
    infinity), which JSON cannot carry back out and no reward or score can mean."""
    number = float(value)
    if not math.isfinite(number):
        raise InputError(f"'{name}' must be a finite number, got {value!r}")
    return number


def _probability(value: Any) -> float:
    p = _finite(value, "p")
    if not 0.0 <= p <= 1.0:
        raise InputError(f"'p' must be in [0, 1], got {p}")
    return p


def _floats(values: Any) -> np.ndarray:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1 or not np.isfinite(arr).all():
        raise InputError("qpos/qvel must be flat lists of finite numbers")
    return arr


def _results(
    bracket: Bracket, matches: list[dict[str, Any]]
) -> tuple[dict[tuple[int, int], int], frozenset[tuple[int, int]]]:
    """Replay the listed matches through the bracket, checking each one's players; the
    results, and the ``(round, slot)`` of the tied ones."""
    results: dict[tuple[int, int], int] = {}
    ties: set[tuple[int, int]] = set()
    pending = {(int(m["round"]), frozenset((int(m["a"]), int(m["b"])))): m for m in matches}
    if len(pending) != len(matches):
        raise InputError("a match is listed twice")
    while open_ := bracket.open_matches(results):
        for m in open_:
            key = (m.round, frozenset((m.a, m.b)))
            if key not in pending:
                raise InputError(f"missing round {m.round} match {m.a} vs {m.b}")
            listed = pending.pop(key)
            winner = int(listed["winner"])
            bracket.check_result(m, winner)
            results[(m.round, m.slot)] = winner
            if _tie(listed, m):
                ties.add((m.round, m.slot))
    if pending:
        raise InputError(f"{len(pending)} listed match(es) are not in the bracket")
    return results, frozenset(ties)


def _tie(listed: dict[str, Any], m: Match) -> bool:
    """The match's ``tie`` flag: absent is False; anything but a JSON bool is an error."""
    tie = listed.get("tie", False)
    if type(tie) is not bool:  # not 1, "true" or null: a flag is a JSON bool
        raise InputError(f"round {m.round} match {m.a} vs {m.b}: 'tie' must be true or false")
    return tie


def _check_tree(doc: TreeDocument, stored: Any) -> None:
    """The stored ``tree`` block must equal the one rebuilt from the matches."""
    if not isinstance(stored, dict) or not isinstance(stored.get("nodes"), list):
        raise InputError("'tree' must be an object with a 'nodes' list")
    nodes = stored["nodes"]
    if stored.get("root") != doc.tree.root or len(nodes) != len(doc.tree):
        raise InputError("'tree' does not match the tree built from 'matches'")
    for n in nodes:
        if not isinstance(n, dict) or not _same_node(n, doc.tree):
            raise InputError("'tree' does not match the tree built from 'matches'")


def _same_node(n: dict[str, Any], tree: PreferenceTree) -> bool:
    state = n.get("state")
    ref = tree.nodes.get(state) if type(state) is int else None  # not a list, bool, float
    reward = n.get("reward")
    if ref is None or not isinstance(reward, int | float) or isinstance(reward, bool):
        return False
    return (n.get("parent"), n.get("height"), n.get("depth"), n.get("weight")) == (
        ref.parent,
        ref.height,
        ref.depth,
        ref.weight,
    ) and math.isclose(reward, ref.reward, abs_tol=1e-9)
