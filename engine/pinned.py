"""A results folder's settings, pinned: written by the first call, checked by every later one,
so that resuming never mixes runs made with different settings."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from engine.errors import InputError

Settings = dict[str, Any]


def pin_settings(
    path: Path, settings: Settings, what: str, normalize: Callable[[Settings], Settings]
) -> None:
    """Write ``settings`` to ``path``, or check that it holds the same ones.

    Args:
        what: the folder's contents in the error ("a reproduction").
        normalize: the saved JSON as ``settings`` would be written now (defaults filled in,
            keys of older versions dropped).

    Raises:
        InputError: ``path`` holds other settings (the message names them), or is no
            settings file.
    """
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(settings, indent=1) + "\n")
        return
    try:
        saved = normalize(json.loads(path.read_text()))
    except (ValueError, TypeError, KeyError) as exc:  # not JSON, or not settings ACV wrote
        raise InputError(
            f"{path} does not hold {what}'s settings ({exc}): choose another --out"
        ) from exc
    changed = [k for k, v in settings.items() if saved.get(k) != v]
    if changed:
        raise InputError(
            f"{path.parent} holds {what} with other settings ({', '.join(changed)}): "
            "resume it as it was or choose another --out"
        )
