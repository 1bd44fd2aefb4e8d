"""``python -m app.jobs.run_process RUN_ID --worker NAME --parent PID``: one run, one process.

The ``local`` executor starts this for every run, with ``DATABASE_URL`` and ``ACV_RUNS_DIR``
in the environment and its output going to the run's ``process.log``. SIGTERM (the worker
stopping) or the death of the worker process stops the run after the current update, with a
checkpoint, as ``interrupted``; on Linux the kernel sends SIGTERM when the worker dies
(``PR_SET_PDEATHSIG``), elsewhere the parent pid is polled.
"""

from __future__ import annotations

import argparse
import ctypes
import logging
import os
import signal
import sys
from types import FrameType

from app.jobs.execute import execute_run
from app.jobs.settings import JobSettings
from app.settings import Settings

_PR_SET_PDEATHSIG = 1


class StopFlag:
    """Set by SIGTERM/SIGINT, or when the parent process is gone."""

    def __init__(self, parent: int | None) -> None:
        self.parent = parent
        self.signalled = False

    def on_signal(self, _signum: int, _frame: FrameType | None) -> None:
        self.signalled = True

    def __call__(self) -> bool:
        return self.signalled or (self.parent is not None and os.getppid() != self.parent)


def die_with_parent() -> None:
    """Ask Linux to send SIGTERM when the parent dies (a no-op elsewhere)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m app.jobs.run_process", description="Execute one claimed training run."
    )
    parser.add_argument("run_id", type=int)
    parser.add_argument("--worker", required=True, help="the claiming worker's name")
    parser.add_argument("--parent", type=int, default=None, help="the worker's pid")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    stop = StopFlag(args.parent)
    signal.signal(signal.SIGTERM, stop.on_signal)
    signal.signal(signal.SIGINT, stop.on_signal)
    die_with_parent()
    if stop():  # the worker died before we could ask to be told
        return 3
    settings = Settings()
    status = execute_run(
        args.run_id,
        database_url=settings.sqlalchemy_url,
        runs_dir=JobSettings().runs_root(settings),
        worker=args.worker,
        interrupted=stop,
    )
    logging.info("run %d: %s", args.run_id, status)
    return 0


if __name__ == "__main__":
    sys.exit(main())
