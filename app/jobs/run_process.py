"""One run, one process: what the ``local`` executor's run processes execute.

:class:`app.jobs.local.LocalExecutor` forks each run from a fork server that has imported
torch and the training code once (:data:`PRELOAD`), then calls :func:`run_child` with the
worker's environment and the run's ``process.log``. SIGTERM (the worker stopping) or the
death of the worker stops the run after the current update, with a checkpoint, as
``interrupted``: the worker's death is seen on the pipe that multiprocessing keeps to the
process that started the child, and the fork server's death (it exits with the worker) by
``PR_SET_PDEATHSIG`` on Linux.
"""

from __future__ import annotations

import ctypes
import logging
import multiprocessing
import os
import signal
import sys
from types import FrameType

from app.jobs.settings import JobSettings
from app.settings import Settings

_PR_SET_PDEATHSIG, _PR_SET_NAME = 1, 15
#: What the fork server imports once for every run process it forks: ``import torch`` takes
#: seconds, and the optimizer's first use imports ``torch._dynamo``, seconds more.
PRELOAD = ("app.jobs.execute", "torch", "torch._dynamo")


def preload() -> list[str]:
    """:data:`PRELOAD`, and ``app.cli`` when ``__main__`` is a script or a module (``acv``'s
    console script, ``python -m app.cli``): multiprocessing runs it again in every child, and
    CPython 3.11's fork server ignores a ``"__main__"`` preload."""
    main = sys.modules["__main__"]
    started_as_a_program = getattr(main, "__file__", None) or getattr(main.__spec__, "name", None)
    return [*PRELOAD, *(["app.cli"] if started_as_a_program else [])]


class StopFlag:
    """Set by SIGTERM/SIGINT, or once the worker that started the run is gone."""

    def __init__(self) -> None:
        self.signalled = False
        self.worker = multiprocessing.parent_process()

    def on_signal(self, _signum: int, _frame: FrameType | None) -> None:
        self.signalled = True

    def __call__(self) -> bool:
        return self.signalled or (self.worker is not None and not self.worker.is_alive())


def _prctl(option: int, value: int | bytes) -> None:
    if sys.platform.startswith("linux"):  # a no-op elsewhere
        ctypes.CDLL(None, use_errno=True).prctl(option, value, 0, 0, 0)


def die_with_parent() -> None:
    """Ask Linux to send SIGTERM when the parent (the fork server) dies."""
    _prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


def name_process(run_id: int) -> None:
    """Name the process ``acv-run-<id>`` for ``ps -o comm``, ``top`` and ``pgrep`` (a forked
    process keeps the fork server's command line)."""
    _prctl(_PR_SET_NAME, f"acv-run-{run_id}".encode()[:15])


def run_child(run_id: int, worker: str, environ: dict[str, str], log_file: str) -> None:
    """The body of a run process: its own session, output and environment, then the run.

    Args:
        run_id: the run ``worker`` has claimed.
        worker: the claiming worker's name.
        environ: the whole environment, as a spawned process would have inherited it.
        log_file: where stdout and stderr go (appended).
    """
    server = os.getppid()  # the fork server, until it dies
    os.setsid()  # terminal signals reach the worker, which stops its runs in order
    name_process(run_id)
    fd = os.open(log_file, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    os.environ.clear()
    os.environ.update(environ)
    sys.exit(_run(run_id, worker, server))


def _run(run_id: int, worker: str, server: int) -> int:
    from app.jobs.execute import execute_run  # preloaded by the fork server; heavy for the web

    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s", force=True
    )
    stop = StopFlag()
    signal.signal(signal.SIGTERM, stop.on_signal)
    signal.signal(signal.SIGINT, stop.on_signal)
    die_with_parent()
    if stop() or os.getppid() != server:  # the worker or the fork server died before we asked
        return 3
    settings = Settings()
    status = execute_run(
        run_id,
        database_url=settings.sqlalchemy_url,
        runs_dir=JobSettings().runs_root(settings),
        worker=worker,
        interrupted=stop,
    )
    logging.info("run %d: %s", run_id, status)
    return 0
