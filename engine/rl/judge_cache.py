"""The judges' per-checkpoint cache, keyed by what was judged rather than where it lies.

A judge that simulates (``behaviour``, ``return``) stores its result under the run directory
(``rollouts/``), in a file named by the checkpoint's *content hash* and the judge's options. A
checkpoint rewritten at the same path and step (a resumed or retrained run) has another hash,
so it never reads a stale result; the same file copied elsewhere hits.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROLLOUT_DIR = "rollouts"


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, hex."""
    with Path(path).open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def array_digest(*arrays: np.ndarray) -> str:
    """A short SHA-256 of arrays' shapes and float64 bytes (for keying by candidates)."""
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a, dtype=np.float64)
        h.update(repr(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()[:16]


def cached_array(run_dir: Path | None, name: str, compute: Callable[[], np.ndarray]) -> np.ndarray:
    """``compute()`` through ``<run_dir>/rollouts/<name>.npy`` (best effort: a cache that cannot
    be read or written costs only time; no cache when ``run_dir`` is None)."""
    if run_dir is None:
        return compute()
    path = Path(run_dir) / ROLLOUT_DIR / f"{name}.npy"
    if path.is_file():
        try:
            cached: np.ndarray = np.load(path)
            return cached
        except (OSError, ValueError):
            pass  # a damaged cache file is a miss
    value = compute()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".npy")
        with os.fdopen(fd, "wb") as f:
            np.save(f, value)
        os.replace(tmp, path)
    except OSError:
        pass
    return value
