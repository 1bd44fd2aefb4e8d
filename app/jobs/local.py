"""The ``local`` executor: each run in its own process on this machine.

A run process (:mod:`app.jobs.run_process`) gets its own session (terminal signals reach the
worker, which then stops its runs in order), writes its output to ``<run dir>/process.log``,
and reports through the database. A process that exits without setting its run's final
state (killed, out of memory, a crash in native code) is reported as :class:`Finished` with
an error made of its exit status and the tail of its log.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from app.db import ROOT
from app.jobs.settings import run_dir

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
    """

    name = "local"
    signals_runs = True  # stop() reaches the runs by SIGTERM

    def __init__(self, *, database_url: str, runs_dir: Path) -> None:
        self.database_url = database_url
        self.runs_dir = Path(runs_dir).resolve()
        self.procs: dict[int, subprocess.Popen] = {}

    def start(self, run_id: int, worker: str) -> None:
        """Start the process of a run ``worker`` has claimed."""
        out = run_dir(self.runs_dir, run_id)
        out.mkdir(parents=True, exist_ok=True)
        env = os.environ | {
            "DATABASE_URL": self.database_url,
            "ACV_RUNS_DIR": str(self.runs_dir),
            "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        }
        with (out / LOG_FILE).open("ab") as log:
            self.procs[run_id] = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "app.jobs.run_process",
                    str(run_id),
                    "--worker",
                    worker,
                    "--parent",
                    str(os.getpid()),
                ],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,
            )

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
            code = proc.poll()
            if code is not None:
                del self.procs[run_id]
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
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)

    def wait(self, timeout_s: float) -> None:
        """Wait for the run processes to exit; kill those still running after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
