"""``acv`` command line. Each module below registers its commands on :data:`root.cli`."""

from __future__ import annotations

import json
import sys

from app.cli import (  # noqa: F401  (registers commands)
    render,
    reproduce,
    serve,
    study,
    tournament,
    train,
    worker,
)
from app.cli.root import cli
from engine.errors import InputError


def main() -> None:
    """Console-script entry point: bad input becomes one stderr line and exit code 2."""
    try:
        cli()
    except (InputError, json.JSONDecodeError, FileNotFoundError, IsADirectoryError,
            PermissionError, UnicodeDecodeError) as exc:
        print(f"acv: error: {exc}", file=sys.stderr)
        sys.exit(2)
