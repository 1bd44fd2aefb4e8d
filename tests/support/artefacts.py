"""Checkpoint artefacts as a run's executor stores them, with scores whose truth is known."""

from __future__ import annotations

from typing import Any

import numpy as np

from engine.rl.report import SCHEMA

#: The per-candidate table's columns (engine.records.CandidateRow).
COLUMNS = ("reward", "advice", "z", "shaping", "shaped", "value", "behaviour")


def report_body(step: int, behaviour: np.ndarray) -> dict[str, Any]:
    """An ``acv.checkpoint/1`` body whose table scores candidate ``i`` ``behaviour[i]`` under
    the ``behaviour`` judge (0 in every other column; no judge's tree)."""
    rows = [
        {"id": i, **dict.fromkeys(COLUMNS, 0.0), "behaviour": float(score)}
        for i, score in enumerate(behaviour)
    ]
    return {"schema": SCHEMA, "step": step, "judges": {}, "candidates": rows}
