"""Where a result came from: ACV's version, the commit of the code that wrote it, and the
versions of the libraries that decide its numbers."""

from __future__ import annotations

import importlib.metadata
import platform
import subprocess
from pathlib import Path
from typing import Any

from engine import __version__

#: The libraries whose versions can change a run's numbers (``test_bit_identity`` pins them).
LIBRARIES = ("torch", "numpy", "mujoco", "gymnasium")
#: The file in a run directory that records :func:`provenance`.
PROVENANCE_FILE = "provenance.json"


def git_commit() -> str | None:
    """The commit of the code that wrote the report (``+dirty`` with local changes); None
    outside a git checkout of ACV (a wheel install: its version says what it is)."""
    root = Path(__file__).resolve().parents[1]  # the checkout, when the engine is in one
    if not (root / ".git").exists():  # never the commit of a repository we are installed in
        return None
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+dirty" if dirty else "")


def provenance() -> dict[str, Any]:
    """What wrote a result: ACV's version, its commit (or None), Python's version and the
    versions of :data:`LIBRARIES` (None for one that is not installed)."""
    return {
        "acv": __version__,
        "commit": git_commit(),
        "python": platform.python_version(),
        "libraries": {name: _installed(name) for name in LIBRARIES},
    }


def _installed(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None
