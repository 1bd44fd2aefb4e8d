"""An ``acv.tree/1`` document as JSON: deterministic, floats kept exact."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from engine.bracket import Match
from engine.candidates import Candidate
from engine.treefile.document import SCHEMA, TreeDocument


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
