"""Content-addressed disk cache of rendered images: (state, view, size, format) -> file.

The key hashes everything the picture depends on, so entries never go stale and need no
invalidation; bump :data:`RENDER_VERSION` when the look changes. Writers write a temporary
file in the same directory and ``os.replace`` it into place, which is atomic on POSIX: two
processes rendering the same state both succeed, and a reader sees a whole file or none.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from engine.render.views import VIEWS, RenderSpec

#: Part of every key: bump it when cameras, lighting or encoding change.
RENDER_VERSION = 1


def cache_key(env_id: str, qpos: np.ndarray, qvel: np.ndarray, spec: RenderSpec) -> str:
    """Hex digest naming the image of state ``(qpos, qvel)`` of ``env_id`` under ``spec``.

    Args:
        env_id: the Gymnasium env id.
        qpos: generalised positions, shape ``(nq,)``; hashed as little-endian float64.
        qvel: generalised velocities, shape ``(nv,)``.
        spec: the render request (the view's camera parameters are hashed, not just its name).
    """
    h = hashlib.blake2b(digest_size=20)
    view = VIEWS[spec.view]
    header = (
        f"acv-render/{RENDER_VERSION}|{env_id}|{view}|{spec.size}|{spec.fmt}|"
        f"{spec.quality}|{np.shape(qpos)}|{np.shape(qvel)}"
    )
    h.update(header.encode())
    for values in (qpos, qvel):
        h.update(np.ascontiguousarray(values, dtype="<f8").tobytes())
    return h.hexdigest()


class RenderCache:
    """A directory of images named by :func:`cache_key`; safe across threads and processes.

    Args:
        root: the cache directory, created on first write.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def path(self, key: str, fmt: str) -> Path:
        """Where the entry lives: two-character fan-out keeps directories small."""
        return self.root / key[:2] / f"{key}.{fmt}"

    def get(self, key: str, fmt: str) -> bytes | None:
        """The cached image bytes, or ``None`` on a miss (or when the cache cannot be read)."""
        try:
            return self.path(key, fmt).read_bytes()
        except OSError:  # missing, or an unreadable cache directory: render instead
            return None

    def put(self, key: str, fmt: str, data: bytes) -> Path:
        """Store ``data`` atomically (temporary file + rename) and return its path."""
        target = self.path(key, fmt)
        write_atomically(target, data)
        return target


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` (a temporary file, then a rename): a reader sees the whole
    file or none, and a crash leaves no half-written picture."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)  # mkstemp makes it owner-only; images are not secret
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
