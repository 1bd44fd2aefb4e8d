"""``acv`` command line. Each module below registers its commands on :data:`root.cli`."""

from __future__ import annotations

import sys

from app.cli.root import cli
from engine.errors import InputError
from engine.mujoco_gl import check_mujoco_gl


def _register_commands() -> None:
    """Import the command modules, which register their commands (and import mujoco)."""
    from app.cli import (  # noqa: F401
        agents,
        evaluate,
        experiment,
        export,
        quality,
        render,
        reproduce,
        serve,
        study,
        survey,
        tournament,
        train,
        validate,
        validate_round2,
        verdict,
        webhook,
        worker,
    )


def _startup_error() -> InputError | None:
    """A bad ``MUJOCO_GL`` makes importing mujoco raise: report it instead of importing."""
    try:
        check_mujoco_gl()
    except InputError as exc:
        return exc
    _register_commands()
    return None


_STARTUP_ERROR = _startup_error()


def main() -> None:
    """Console-script entry point. Bad input becomes one stderr line and exit code 2: a bad
    ``MUJOCO_GL`` here, anything below a command in :class:`app.cli.root._Commands`."""
    if _STARTUP_ERROR is not None:
        print(f"acv: error: {_STARTUP_ERROR}", file=sys.stderr)
        sys.exit(2)
    cli()
