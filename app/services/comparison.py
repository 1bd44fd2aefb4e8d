"""The Human and the Agent Preference Tree of a run, and their conformance ("anytime").

At any checkpoint the run's advice bracket is replayed with the agent as the judge
(:func:`engine.rl.agent_judge.agent_tree`); the metrics are exactly those of ``acv compare
--json`` (:func:`engine.conformance.compare`). Agent trees are cached in the run directory
(``agent_trees/``), keyed by checkpoint, judge and the checkpoint file's modification time,
so a conformance curve over many checkpoints is computed once.
"""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any

from engine.conformance import compare
from engine.errors import InputError
from engine.treefile import TreeDocument, tree_from_json, tree_to_json

CACHE_DIR = "agent_trees"
#: Columns of the conformance CSV exports (one row per checkpoint).
CSV_COLUMNS = ("checkpoint", "n_matches", "n_agree", "match_agreement", "match_agreement_ci_low",
               "match_agreement_ci_high", "kendall_tau_b", "tree_edit_distance",
               "same_champion", "n_rejected")
_EPISODE_KEYS = ("episode_returns", "episode_shaped_returns")


def checkpoints(out: Path) -> list[int]:
    """The timesteps of the run's checkpoints, in increasing order."""
    from engine.rl.checkpoint import list_checkpoints  # torch loads on first use

    return list(list_checkpoints(out))


def pick_checkpoint(out: Path, step: int | None) -> int:
    """``step`` if the run has it, else (for None) its latest checkpoint.

    Raises:
        InputError: no checkpoint yet, or none at ``step``.
    """
    steps = checkpoints(out)
    if not steps:
        raise InputError("the run has no checkpoint yet")
    if step is None:
        return steps[-1]
    if step not in steps:
        raise InputError(f"the run has no checkpoint at step {step}; it has "
                         f"{', '.join(map(str, steps))}")
    return step


def agent_doc(out: Path, step: int, advice: TreeDocument, judge: str = "shaped") -> TreeDocument:
    """The Agent Preference Tree at checkpoint ``step`` (cached on disk)."""
    from engine.rl.agent_judge import agent_tree
    from engine.rl.checkpoint import checkpoint_path

    mtime = checkpoint_path(out, step).stat().st_mtime_ns
    cached = out / CACHE_DIR / f"step_{step}.{judge}.{mtime}.json"
    if cached.is_file():
        return tree_from_json(json.loads(cached.read_text()))
    doc = agent_tree(out, step, judge=judge, advice=advice)
    _write_atomic(cached, json.dumps(tree_to_json(doc)))
    return doc


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def conformance(human: TreeDocument, agent: TreeDocument) -> dict[str, Any]:
    """The metrics JSON of ``acv compare --json``."""
    return compare(human, agent).to_json()


def conformance_curve(out: Path, advice: TreeDocument,
                      judge: str = "shaped") -> list[dict[str, Any]]:
    """The conformance metrics at every checkpoint: ``{"checkpoint": step, **metrics}``."""
    return [{"checkpoint": step, **conformance(advice, agent_doc(out, step, advice, judge))}
            for step in checkpoints(out)]


def verdict(metrics: dict[str, Any], whose: str = "your") -> str:
    """One plain sentence: ``the agent kept 14 of 15 of your choices ...``."""
    kept, n = metrics["n_agree"], metrics["n_matches"]
    rejected = n - kept
    text = f"The agent kept {kept} of {n} of {whose} choices"
    text += " and rejected none." if rejected == 0 else \
        f" and overturned {rejected} ({1 - kept / n:.0%})."
    champion = "It agrees on the champion." if metrics["same_champion"] else \
        "It crowns a different champion."
    return f"{text} {champion}"


def csv_text(rows: list[dict[str, Any]]) -> str:
    """Conformance metrics (one dict per checkpoint) as CSV with :data:`CSV_COLUMNS`."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in rows:
        low, high = row["match_agreement_ci"]
        writer.writerow((row["checkpoint"], row["n_matches"], row["n_agree"],
                         row["match_agreement"], low, high, row["kendall_tau_b"],
                         row["tree_edit_distance"], row["same_champion"], len(row["rejected"])))
    return out.getvalue()


def metrics_rows(out: Path, after: int = -1) -> list[dict[str, Any]]:
    """The run's metrics rows (without per-episode lists) with timesteps above ``after``."""
    path = out / "metrics.jsonl"
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:  # a line being written right now
            continue
        if row.get("timesteps", 0) > after:
            rows.append({k: v for k, v in row.items() if k not in _EPISODE_KEYS})
    return rows
