"""Atomic, self-describing checkpoints: ``checkpoints/step_<timesteps>.pt``.

A checkpoint holds everything needed to rebuild the policy, critics, normalisers and z_phi
(for the agent preference tree) and to continue the run exactly (optimisers, random
generators, env snapshots). It is a plain ``torch.save`` dict loadable with
``weights_only=True``, so opening a foreign file cannot run code.
"""

from __future__ import annotations

import os
import pickle
import re
import tempfile
import zipfile
from pathlib import Path
from typing import Any

from engine.errors import InputError

FORMAT = "acv.checkpoint/1"
_NAME = re.compile(r"^step_(\d+)\.pt$")


def checkpoint_dir(run_dir: Path) -> Path:
    """The ``checkpoints`` folder of a run."""
    return Path(run_dir) / "checkpoints"


def checkpoint_path(run_dir: Path, timesteps: int) -> Path:
    """``<run>/checkpoints/step_<timesteps>.pt``."""
    return checkpoint_dir(run_dir) / f"step_{timesteps}.pt"


def save_checkpoint(state: dict[str, Any], run_dir: Path, timesteps: int) -> Path:
    """Write ``state`` atomically (temp file in the same folder, then ``os.replace``)."""
    path = checkpoint_path(run_dir, timesteps)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".pt")
    try:
        with os.fdopen(fd, "wb") as f:
            import torch  # here: finding a checkpoint's path needs no torch (the web process)

            torch.save({"format": FORMAT, "timesteps": timesteps, **state}, f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a checkpoint is an ordinary file
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def list_checkpoints(run_dir: Path) -> dict[int, Path]:
    """Timesteps -> checkpoint path, in increasing order (temp files are ignored)."""
    folder = checkpoint_dir(run_dir)
    found = {}
    if folder.is_dir():
        for path in folder.iterdir():
            if match := _NAME.match(path.name):
                found[int(match.group(1))] = path
    return dict(sorted(found.items()))


def find_checkpoint(run_dir: Path, step: int | None = None) -> Path:
    """The checkpoint at ``step``, or the latest one.

    Raises:
        InputError: the run has no (such) checkpoint.
    """
    found = list_checkpoints(run_dir)
    if not found:
        raise InputError(
            f"{run_dir} has no checkpoints (expected {checkpoint_dir(run_dir)}/step_<timesteps>.pt)"
        )
    if step is None:
        return found[max(found)]
    if step not in found:
        raise InputError(
            f"{run_dir} has no checkpoint at step {step}; it has {', '.join(map(str, found))}"
        )
    return found[step]


def load_checkpoint(path: Path) -> dict[str, Any]:
    """Load and check a checkpoint.

    Raises:
        InputError: the file is missing, corrupt, or not an ACV checkpoint.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no checkpoint file {path}")
    try:
        import torch  # here, as in save_checkpoint

        state = torch.load(path, map_location="cpu", weights_only=True)
    except (
        RuntimeError,
        pickle.UnpicklingError,
        zipfile.BadZipFile,
        EOFError,
        ValueError,
        OSError,
    ) as exc:
        raise InputError(f"{path} is not a readable checkpoint ({type(exc).__name__})") from exc
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise InputError(f"{path} is not an ACV checkpoint (expected format {FORMAT})")
    return state
