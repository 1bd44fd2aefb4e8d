"""The ``acv`` command line, as tests run it: in this process (fast, monkeypatchable) or in a
fresh interpreter (exactly as a user runs it)."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from typer.testing import CliRunner, Result


def acv(*args: object) -> Result:
    """Run ``acv ARGS`` in this process; the result has ``exit_code``, ``output``, ``stderr``."""
    from app.cli import cli

    with logging_kept():
        return CliRunner().invoke(cli, [str(a) for a in args])


@contextmanager
def logging_kept() -> Iterator[None]:
    """Put every logger back as it was: ``acv serve`` and ``acv worker`` configure logging to
    CliRunner's stderr, which is closed once the call returns, so a thread's later line (a
    webhook delivery's) would print a "Logging error" instead."""
    manager = logging.Logger.manager
    kept = {name: _state(logger) for name, logger in _loggers(manager).items()}
    root = _state(logging.getLogger())
    try:
        yield
    finally:
        _restore(logging.getLogger(), root)
        for name, logger in _loggers(manager).items():
            _restore(logger, kept.get(name, ([], logging.NOTSET, True, False)))


def _loggers(manager: logging.Manager) -> dict[str, logging.Logger]:
    return {n: g for n, g in manager.loggerDict.items() if isinstance(g, logging.Logger)}


def _state(logger: logging.Logger) -> tuple[list[logging.Handler], int, bool, bool]:
    return list(logger.handlers), logger.level, logger.propagate, logger.disabled


def _restore(logger: logging.Logger, state: tuple[list[logging.Handler], int, bool, bool]) -> None:
    handlers, level, propagate, disabled = state
    logger.handlers[:] = handlers
    logger.setLevel(level)
    logger.propagate, logger.disabled = propagate, disabled


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
