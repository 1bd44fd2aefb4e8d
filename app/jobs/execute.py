"""One training run from start to end, wherever it executes (a local process, a Ray task).

The run's row says what to train (config, advice tree or pool of trees, resume flag);
:func:`execute_run` calls :func:`engine.rl.runner.train` in the run directory, stores every
metrics row and saved checkpoint as rows (:mod:`app.runs.run_state`), judges every checkpoint
once and stores the result as the checkpoint's artefact (:mod:`app.runs.artefacts`; the web
tier only reads it; an imported policy is judged instead of trained,
:mod:`app.runs.imported_judge`), polls for a cancel (or for the run being taken away, e.g. marked
``interrupted`` after a restart) after every update, and sets the final state. A stop always
writes a checkpoint first (``train`` does), so an interrupted or cancelled run can resume.
"""

from __future__ import annotations

import fcntl
import logging
import os
import time
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from app.db import make_engine, make_sessions
from app.jobs import queue
from app.jobs.settings import SPLIT_ENV, run_dir
from app.models import Run, RunStatus
from app.runs import artefacts, run_state
from app.runs.imported import is_imported
from engine.errors import InputError

log = logging.getLogger(__name__)
LOCK_FILE = ".lock"
#: Seconds a run waits for the previous process of the same run directory to let go.
LOCK_WAIT_S = 60.0


def execute_run(
    run_id: int,
    *,
    database_url: str,
    runs_dir: str | Path,
    worker: str,
    interrupted: Callable[[], bool] | None = None,
) -> str:
    """Train run ``run_id``, which ``worker`` has claimed; returns the state it ends in.

    Args:
        run_id: the run's id.
        database_url: where the ``runs`` table is.
        runs_dir: the folder of run directories (shared storage for Ray).
        worker: the claiming worker's name; the run is abandoned if it changes.
        interrupted: polled after every update; True stops the run as ``interrupted`` (the
            local process sets it on SIGTERM or when its worker dies).

    Never raises for a failing run: the error is stored (state ``failed``) and logged.
    """
    engine = make_engine(database_url)
    try:
        out = run_dir(runs_dir, run_id)
        return _Job(
            make_sessions(engine), run_id, worker, interrupted or (lambda: False), out
        ).run()
    finally:
        engine.dispose()


class _Job:
    """The state of one execution of the run in ``out``: why it stopped, if it did."""

    def __init__(
        self,
        sessions: sessionmaker[Session],
        run_id: int,
        worker: str,
        interrupted: Callable[[], bool],
        out: Path,
    ) -> None:
        self.sessions, self.run_id, self.worker = sessions, run_id, worker
        self.interrupted, self.out = interrupted, out
        self.reason: str | None = None  # cancel, lost, interrupted

    def run(self) -> str:
        out = self.out
        with self.sessions() as session:
            row = session.get(Run, self.run_id)
        if row is None or row.worker != self.worker or row.status != RunStatus.RUNNING:
            return "lost"
        try:
            with run_lock(out):
                if row.resume:  # a run trained before run state rows: its earlier rows first
                    with self.sessions() as session:
                        run_state.import_folder(session, run_id=self.run_id, out=out)
                if is_imported(row):  # a policy from elsewhere: judged, never trained
                    if not self.judge_imported(out.parent):
                        return "lost"
                else:
                    _train(
                        row,
                        out,
                        self.progress,
                        self.should_stop,
                        self.judge_checkpoint(row, out),
                        self.env_processes(),
                    )
        except Exception as exc:  # any failure must end up on the run, not in a log only
            log.error("run %d failed:\n%s", self.run_id, traceback.format_exc())
            return self._finish(RunStatus.FAILED, error_text(exc))
        final = {
            None: RunStatus.SUCCEEDED,
            "cancel": RunStatus.CANCELLED,
            "interrupted": RunStatus.INTERRUPTED,
        }
        if self.reason == "lost":
            return "lost"
        return self._finish(
            final[self.reason], queue.INTERRUPTED if self.reason == "interrupted" else None
        )

    def _finish(self, status: str, error: str | None = None) -> str:
        with self.sessions() as session:
            done = queue.finish(
                session, run_id=self.run_id, worker=self.worker, status=status, error=error
            )
        return status if done else "lost"

    def progress(self, row: dict[str, Any]) -> None:
        """Store the update: the run's progress, its metrics row, and its checkpoint when the
        runner saved one at this step (it saves before it reports)."""
        saved = artefacts.checkpoint_file(self.out, int(row["timesteps"])).is_file()
        with self.sessions() as session:
            ours = run_state.record_update(
                session, run_id=self.run_id, owner=queue.ours(self.run_id, self.worker), row=row,
                saved=saved,
            )  # fmt: skip
        if not ours:
            self.reason = self.reason or "lost"

    def judge_imported(self, runs_root: Path) -> bool:
        """Judge an imported policy (:mod:`app.runs.imported_judge`); whether the run was
        still ours when its report was stored (a cancel or a stop meanwhile stores nothing,
        and the run ends as :attr:`reason` says)."""
        from app.runs.imported_judge import judge_imported  # torch, MuJoCo, onnxruntime

        owner = queue.ours(self.run_id, self.worker)
        return judge_imported(
            self.sessions,
            run_id=self.run_id,
            runs_root=runs_root,
            owner=owner,
            should_stop=self.should_stop,
        )

    def judge_checkpoint(self, row: Run, out: Path) -> Callable[[int, Path], None] | None:
        """The ``on_checkpoint`` hook: store the checkpoint's artefact (runs with advice)."""
        advice, pool = row.advice, row.advice_pool
        if advice is None:
            return None

        def judge(step: int, _: Path) -> None:
            try:
                artefacts.record(
                    self.sessions, run_id=self.run_id, advice=advice, out=out, step=step, pool=pool
                )
            except Exception:  # a judge failing must not fail the training; backfill retries
                log.error(
                    "run %d, checkpoint %d: no artefact:\n%s",
                    self.run_id,
                    step,
                    traceback.format_exc(),
                )

        return judge

    def env_processes(self) -> int:
        """2 when the worker lets a lone run take the second core (``ACV_SPLIT_LONE_RUN``)
        and no other run is running now, else 1. Either gives the same numbers."""
        if os.environ.get(SPLIT_ENV) != "1":
            return 1
        with self.sessions() as session:
            alone = queue.running_besides(session, run_id=self.run_id) == 0
        processes = 2 if alone else 1
        log.info("run %d: its envs step in %d process(es)", self.run_id, processes)
        return processes

    def should_stop(self) -> bool:
        if self.reason is None and self.interrupted():
            self.reason = "interrupted"
        if self.reason is None:
            with self.sessions() as session:
                self.reason = queue.stop_reason(session, run_id=self.run_id, worker=self.worker)
        return self.reason is not None


def _train(
    row: Run,
    out: Path,
    progress: Callable[[dict[str, Any]], None],
    should_stop: Callable[[], bool],
    on_checkpoint: Callable[[int, Path], None] | None,
    env_processes: int = 1,
) -> None:
    from engine.rl.config import TrainConfig  # torch loads here, in the run's process
    from engine.rl.runner import train
    from engine.treefile import tree_from_json

    advice: Any = tree_from_json(row.advice) if row.advice is not None else None
    if row.advice_pool:  # pooled: F is the (config.pool_weights) mean of the trees' F
        advice = [tree_from_json(m["tree"]) for m in row.advice_pool]
    train(
        TrainConfig.from_json(row.config),
        advice,
        out,
        progress=progress,
        should_stop=should_stop,
        resume=row.resume,
        on_checkpoint=on_checkpoint,
        env_processes=env_processes,
    )


def error_text(exc: BaseException) -> str:
    """A failure for people: bad input as its message, anything else with its type."""
    if isinstance(exc, InputError):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


@contextmanager
def run_lock(out: Path, wait_s: float = LOCK_WAIT_S) -> Iterator[None]:
    """Hold the run directory's lock file, so that a resumed run never overlaps the process
    that is still writing its last checkpoint.

    Raises:
        RuntimeError: another process held the lock for ``wait_s`` seconds.
    """
    out.mkdir(parents=True, exist_ok=True)
    fd = os.open(out / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        deadline = time.monotonic() + wait_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"another process is using {out}") from None
                time.sleep(0.2)
        yield
    finally:
        os.close(fd)  # closing releases the lock
