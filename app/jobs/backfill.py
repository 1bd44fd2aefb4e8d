"""Automatic backfill: checkpoints of ended runs get their artefacts without anyone asking.

A run's executor judges each checkpoint as it writes it, but not the one a stop writes (so that
stopping stays quick), nor, of course, those of runs that ended before artefacts existed or
whose judging failed. An idle worker therefore looks now and then for ended runs with
unjudged checkpoints and, if there are any, starts ``python -m app.jobs.backfill`` to judge
them: a process of its own, because judging loads torch and MuJoCo, which the web process that
hosts the worker thread must never import (:mod:`app.runs.artefacts`).
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from pathlib import Path

from sqlalchemy.orm import Session, sessionmaker

from app.core.logs import configure_logging
from app.core.resources import child_pythonpath
from app.db import make_engine, make_sessions
from app.runs import artefacts, run_state
from app.settings import Settings

log = logging.getLogger(__name__)


class Backfiller:
    """Starts one backfill process at a time while the worker is idle.

    Args:
        sessions: database sessions (to look for missing artefacts).
        database_url: passed to the process as ``DATABASE_URL`` (never on its command line).
        runs_dir: the folder of run directories.
        every_s: seconds between two looks.
    """

    def __init__(
        self, sessions: sessionmaker[Session], *, database_url: str, runs_dir: Path, every_s: float
    ) -> None:
        self.sessions, self.database_url = sessions, database_url
        self.runs_dir, self.every_s = Path(runs_dir).resolve(), every_s
        self.proc: subprocess.Popen[bytes] | None = None
        self._look_at = 0.0

    def tick(self, *, idle: bool) -> None:
        """Start a backfill process if the worker is idle, none is running and one is due."""
        if self.proc is not None and self.proc.poll() is None:
            return
        self.proc = None
        now = time.monotonic()
        if not idle or now < self._look_at:
            return
        self._look_at = now + self.every_s
        run_state.import_folders(self.sessions, runs_root=self.runs_dir)  # runs from before rows
        with self.sessions() as session:
            if not artefacts.missing(session, runs_root=self.runs_dir):
                return
        log.info("checkpoints without artefacts: starting a backfill process")
        env = os.environ | {
            "DATABASE_URL": self.database_url,
            "ACV_RUNS_DIR": str(self.runs_dir),
            "PYTHONPATH": child_pythonpath(),
        }
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "app.jobs.backfill"], stdin=subprocess.DEVNULL, env=env
        )

    def stop(self) -> None:
        """Stop a backfill in progress (what it stored stays; the next look redoes the rest)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait()


def backfill_all(sessions: sessionmaker[Session], *, runs_root: Path) -> int:
    """Import the run folders of runs from before run state rows, then judge every unjudged
    checkpoint of ended runs; returns the artefacts stored."""
    run_state.import_folders(sessions, runs_root=runs_root)
    return artefacts.backfill(sessions, runs_root=runs_root)


def main() -> None:
    """Judge every unjudged checkpoint of ended runs (``DATABASE_URL``, ``ACV_RUNS_DIR``)."""
    configure_logging(Settings().log_format)  # its lines join the server's, alike
    engine = make_engine(os.environ["DATABASE_URL"])
    try:
        done = backfill_all(make_sessions(engine), runs_root=Path(os.environ["ACV_RUNS_DIR"]))
    finally:
        engine.dispose()
    log.info("backfill: %d checkpoint artefact(s) stored", done)


if __name__ == "__main__":
    main()
