"""The ``acv`` command line, as tests run it: in this process (fast, monkeypatchable) or in a
fresh interpreter (exactly as a user runs it)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from click.testing import Result
from typer.testing import CliRunner


def acv(*args: object) -> Result:
    """Run ``acv ARGS`` in this process; the result has ``exit_code``, ``output``, ``stderr``."""
    from app.cli import cli

    return CliRunner().invoke(cli, [str(a) for a in args])


def acv_process(
    *args: object,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    timeout_s: float = 120.0,
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m app.cli ARGS`` in a subprocess (in ``cwd``, with ``env`` over this
    process's environment), capturing its text output."""
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *map(str, args)],
        cwd=cwd,
        env=os.environ | (env or {}),
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )
