"""One run in its own process: :func:`run_child`, or ``python -m app.jobs.run_process RUN_ID
--worker NAME --parent PID`` (settings from the environment).

The ``local`` executor forks :func:`run_child` from a fork server that has already imported
torch and the training code, so a run starts in milliseconds rather than seconds. The process
leads its own session (terminal signals go to the worker, which stops its runs in order),
writes its output to the run's ``process.log``, and reports through the database. SIGTERM
(the worker stopping) or the death of its parent stops the run after the current update, with
a checkpoint, as ``interrupted``; on Linux the kernel sends SIGTERM when the parent dies
(``PR_SET_PDEATHSIG``), elsewhere the parent pid is polled. The fork server exits with the
worker, so a dead worker takes its runs down in order.
"""

from __future__ import annotations

import argparse
import ctypes
import logging
import os
import signal
import sys
from pathlib import Path
from types import FrameType

from app.jobs.execute import execute_run, run_dir
from app.jobs.settings import JobSettings
from app.settings import Settings

LOG_FILE = "process.log"
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


def _log_to(path: Path) -> None:
    """Send this process's stdout, stderr and logging to ``path`` (appending)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    sys.stdout.flush()
    sys.stderr.flush()
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s",
                        stream=sys.stderr, force=True)


def run_child(run_id: int, *, worker: str, database_url: str, runs_dir: str,
              parent: int | None = None, new_session: bool = True) -> int:
    """Execute a claimed run in this (fresh) process; returns the exit code.

    Args:
        parent: the pid whose death stops the run; by default this process's parent.
        new_session: lead a new session and log to the run's ``process.log``.
    """
    parent = os.getppid() if parent is None else parent
    if new_session:
        os.setsid()
        _log_to(run_dir(runs_dir, run_id) / LOG_FILE)
    stop = StopFlag(parent)
    signal.signal(signal.SIGTERM, stop.on_signal)
    signal.signal(signal.SIGINT, stop.on_signal)
    die_with_parent()
    if stop():  # the parent died before we could ask to be told
        return 3
    status = execute_run(run_id, database_url=database_url, runs_dir=runs_dir, worker=worker,
                         interrupted=stop)
    logging.info("run %d: %s", run_id, status)
    return 0


def process_main(run_id: int, worker: str, database_url: str, runs_dir: str) -> None:
    """The target of a forked run process: :func:`run_child`, its result as the exit code."""
    sys.exit(run_child(run_id, worker=worker, database_url=database_url, runs_dir=runs_dir))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m app.jobs.run_process",
                                     description="Execute one claimed training run.")
    parser.add_argument("run_id", type=int)
    parser.add_argument("--worker", required=True, help="the claiming worker's name")
    parser.add_argument("--parent", type=int, default=None, help="the worker's pid")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    settings = Settings()
    return run_child(args.run_id, worker=args.worker, database_url=settings.sqlalchemy_url,
                     runs_dir=str(JobSettings().runs_root(settings)), parent=args.parent,
                     new_session=False)


if __name__ == "__main__":
    sys.exit(main())
