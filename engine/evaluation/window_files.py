"""A run's stimulus windows as one ``.npz`` file (:func:`engine.evaluation.stimuli.cached_windows`
keeps them, so that the clips rendered after the stills roll nothing out again).

Plain arrays only, read with ``allow_pickle=False``.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from engine.evaluation.clips import Window


def dump_windows(windows: list[Window]) -> bytes:
    """The windows as ``.npz`` bytes: their states end to end, and each one's length, still
    frame, start and frame duration."""
    meta = np.array([[len(w.qpos), w.still_frame, w.start] for w in windows], dtype=np.int64)
    qpos, qvel = (
        np.concatenate([w.qpos for w in windows]),
        np.concatenate([w.qvel for w in windows]),
    )
    out = io.BytesIO()
    np.savez(out, meta=meta, frame_ms=[w.frame_ms for w in windows], qpos=qpos, qvel=qvel)
    return out.getvalue()


def load_windows(path: Path) -> list[Window]:
    """The windows :func:`dump_windows` wrote to ``path``."""
    with np.load(path, allow_pickle=False) as data:
        meta, frame_ms, qpos, qvel = (data[k] for k in ("meta", "frame_ms", "qpos", "qvel"))
    ends = np.cumsum(meta[:, 0])
    return [
        Window(i, qpos[end - n : end], qvel[end - n : end], float(frame_ms[i]), int(f), int(t))
        for i, ((n, f, t), end) in enumerate(zip(meta, ends, strict=True))
    ]
