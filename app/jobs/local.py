"""The ``local`` executor: each run in its own process on this machine.

Run processes are forked from a ``multiprocessing`` fork server that imports torch and the
training code once (:data:`PRELOAD`), so a run starts at once instead of after seconds of
imports; each is still a fresh process of its own (:func:`app.jobs.run_process.run_child`):
its own session, its output in ``<run dir>/process.log``, its reports in the database. A
process that exits without setting its run's final state (killed, out of memory, a crash in
native code) is reported as :class:`Finished` with an error made of its exit status and the
tail of its log.
"""

from __future__ import annotations

import multiprocessing
import signal
import time
from dataclasses import dataclass
from multiprocessing.process import BaseProcess
from pathlib import Path

from app.jobs.execute import run_dir
from app.jobs.run_process import LOG_FILE, process_main

#: Modules the fork server imports before forking run processes.
PRELOAD = ["app.jobs.run_process", "engine.rl.runner", "engine.rl.agent_judge"]
#: Characters of a dead process's log quoted in its run's error.
TAIL_CHARS = 1500


@dataclass(frozen=True)
class Finished:
    """A run whose process or task ended; ``error`` is None for a clean exit."""

    run_id: int
    error: str | None


def _context() -> multiprocessing.context.BaseContext:
    """The fork-server context (fork start on platforms without one)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)
    return ctx


class LocalExecutor:
    """Runs each claimed run in a process of its own.

    Args:
        database_url: the database the run processes report to.
        runs_dir: the folder of run directories.
    """

    name = "local"
    signals_runs = True  # request_stop() reaches the runs by SIGTERM

    def __init__(self, *, database_url: str, runs_dir: Path) -> None:
        self.database_url = database_url
        self.runs_dir = Path(runs_dir).resolve()
        self.procs: dict[int, BaseProcess] = {}
        self._ctx = _context()

    def start(self, run_id: int, worker: str) -> None:
        """Start the process of a run ``worker`` has claimed."""
        run_dir(self.runs_dir, run_id).mkdir(parents=True, exist_ok=True)
        proc = self._ctx.Process(target=process_main, name=f"acv-run-{run_id}",
                                 args=(run_id, worker, self.database_url, str(self.runs_dir)))
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
            if not proc.is_alive():
                del self.procs[run_id]
                code = proc.exitcode
                done.append(Finished(run_id, None if code == 0 else self._death(run_id, code)))
                proc.close()
        return done

    def _death(self, run_id: int, code: int | None) -> str:
        how = (f"was killed by {signal.Signals(-code).name}" if code is not None and code < 0
               else f"exited with code {code}")
        path = run_dir(self.runs_dir, run_id) / LOG_FILE
        tail = path.read_text(errors="replace")[-TAIL_CHARS:].strip() if path.exists() else ""
        return f"the run process {how}" + (f"; its last output:\n{tail}" if tail else "")

    def request_stop(self) -> None:
        """Ask every run process to stop after its current update (SIGTERM)."""
        for proc in self.procs.values():
            if proc.is_alive():
                proc.terminate()

    def wait(self, timeout_s: float) -> None:
        """Wait for the run processes to exit; kill those still running after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            proc.join(max(0.0, deadline - time.monotonic()))
            if proc.is_alive():
                proc.kill()
                proc.join()
