"""The ``local`` executor: each run in its own process on this machine.

Run processes are forked by multiprocessing's fork server, which imports torch and the
training code once (:func:`app.jobs.run_process.preload`), so that a run starts in a fraction
of a second instead of the seconds those imports take (the server itself starts with the
first run). A run process (:func:`app.jobs.run_process.run_child`) gets its own session
(terminal signals reach the worker, which then stops its runs in order), writes its output to
``<run dir>/process.log``, and reports through the database. A process that exits without
setting its run's final state (killed, out of memory, a crash in native code) is reported as
:class:`Finished` with an error made of its exit status and the tail of its log.
"""

from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass
from multiprocessing.context import ForkServerContext
from multiprocessing.process import BaseProcess
from pathlib import Path

from app.core.resources import child_pythonpath
from app.jobs.run_process import preload, run_child
from app.jobs.settings import SPLIT_ENV, run_dir

LOG_FILE = "process.log"
#: Characters of a dead process's log quoted in its run's error.
TAIL_CHARS = 1500


@dataclass(frozen=True)
class Finished:
    """A run whose process or task ended; ``error`` is None for a clean exit."""

    run_id: int
    error: str | None


class LocalExecutor:
    """Runs each claimed run in a subprocess.

    Args:
        database_url: passed to the run processes as ``DATABASE_URL``.
        runs_dir: the folder of run directories.
        split_lone_runs: a run that starts while no other run is running steps half of its
            envs in a helper process (``ACV_SPLIT_LONE_RUN``; the run process checks).
    """

    name = "local"
    signals_runs = True  # stop() reaches the runs by SIGTERM

    def __init__(self, *, database_url: str, runs_dir: Path, split_lone_runs: bool = False) -> None:
        self.database_url = database_url
        self.split_lone_runs = split_lone_runs
        self.runs_dir = Path(runs_dir).resolve()
        self.procs: dict[int, BaseProcess] = {}

    def start(self, run_id: int, worker: str) -> None:
        """Start the process of a run ``worker`` has claimed."""
        out = run_dir(self.runs_dir, run_id)
        out.mkdir(parents=True, exist_ok=True)
        env = os.environ | {
            "DATABASE_URL": self.database_url,
            "ACV_RUNS_DIR": str(self.runs_dir),
            "PYTHONPATH": child_pythonpath(),
            SPLIT_ENV: "1" if self.split_lone_runs else "0",
        }
        proc = fork_server().Process(
            target=run_child,
            args=(run_id, worker, env, str(out / LOG_FILE)),
            name=f"acv-run-{run_id}",
            daemon=True,  # at the worker's exit, multiprocessing stops it (SIGTERM) and waits
        )
        proc.start()
        self.procs[run_id] = proc

    @property
    def active(self) -> int:
        return len(self.procs)

    def pid(self, run_id: int) -> int | None:
        """The process id of a run started here (for operators and tests)."""
        proc = self.procs.get(run_id)
        return proc.pid if proc is not None else None

    def poll(self) -> list[Finished]:
        """Runs whose process has exited since the last call."""
        done = []
        for run_id, proc in list(self.procs.items()):
            code = proc.exitcode
            if code is not None:
                del self.procs[run_id]
                proc.close()
                done.append(Finished(run_id, None if code == 0 else self._death(run_id, code)))
        return done

    def _death(self, run_id: int, code: int) -> str:
        how = (
            f"was killed by {signal.Signals(-code).name}"
            if code < 0
            else f"exited with code {code}"
        )
        path = run_dir(self.runs_dir, run_id) / LOG_FILE
        tail = path.read_text(errors="replace")[-TAIL_CHARS:].strip() if path.exists() else ""
        return f"the run process {how}" + (f"; its last output:\n{tail}" if tail else "")

    def request_stop(self) -> None:
        """Ask every run process to stop after its current update (SIGTERM)."""
        for proc in self.procs.values():
            if proc.exitcode is None:
                proc.terminate()

    def wait(self, timeout_s: float) -> None:
        """Wait for the run processes to exit; kill those still running after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            proc.join(timeout=max(0.0, deadline - time.monotonic()))
            if proc.exitcode is None:
                proc.kill()
                proc.join()


@functools.cache
def fork_server() -> ForkServerContext:
    """multiprocessing's fork server context, preloading what every run imports (decided once:
    the server starts with the first run and keeps its preload)."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(preload())
    return context
