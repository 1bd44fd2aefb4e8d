"""Start-up checks of the data dir: it exists (or can be made), takes writes, and has room.

A server started on a read-only or full data dir would accept a study and only then fail to
store its images, or refuse the first label a participant sends: better one clear error
before serving (``acv serve`` prints it and exits with code 2).
"""

from __future__ import annotations

import os
import secrets
import shutil
from pathlib import Path

from app.settings import Settings
from engine.errors import InputError

_MIB = 1 << 20
#: Bytes written (and synced) by the probe: enough that a full disk refuses it.
_PROBE_BYTES = 64 << 10


def check_data_dir(settings: Settings) -> None:
    """Make sure ``settings.data_dir`` is a writable directory with enough free space.

    Raises:
        InputError: it cannot be created or written, or has less than
            ``settings.min_free_mb`` MiB free.
    """
    path = settings.data_dir
    if path.exists() and not path.is_dir():
        raise InputError(f"the data dir {path} is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        free = shutil.disk_usage(path).free
        if free < settings.min_free_mb * _MIB:
            raise InputError(
                f"the data dir {path} has only {free / _MIB:.1f} MiB free; ACV "
                f"needs at least {settings.min_free_mb} MiB (ACV_MIN_FREE_MB)"
            )
        _write_probe(path)
    except OSError as exc:
        raise InputError(
            f"cannot write to the data dir {path}: {exc.strerror or type(exc).__name__}"
        ) from None


def _write_probe(path: Path) -> None:
    """Write, sync and delete a small file (catches read-only mounts even for root)."""
    probe = path / f".write-probe-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        with probe.open("wb") as f:
            f.write(bytes(_PROBE_BYTES))
            f.flush()
            os.fsync(f.fileno())
    finally:
        probe.unlink(missing_ok=True)
