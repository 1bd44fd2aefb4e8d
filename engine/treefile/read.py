"""Reading an ``acv.tree/1`` document: every field validated, the tree rebuilt from the
matches and compared with the stored one; :class:`~engine.errors.InputError` on anything else."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from engine.bracket import Bracket, Match
from engine.candidates import Candidate
from engine.errors import InputError, check_seed
from engine.preference_tree import PreferenceTree
from engine.treefile.document import SCHEMA, TreeDocument, make_document


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
