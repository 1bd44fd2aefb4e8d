"""The worker loop: claim queued runs, hand them to an executor, watch them end.

One loop per worker: reap runs whose process or task ended (one that died without setting
its final state is ``failed`` with its error), renew the heartbeat of the runs it looks after,
now and then mark the runs of vanished workers ``interrupted``, and claim queued runs while
it has free slots. Stopping asks the runs to stop (each writes a checkpoint) and leaves them
``interrupted``, to be resumed later.

The web server starts one worker on a thread (:func:`start_app_worker`); ``acv worker`` runs
one in the foreground.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Protocol

from fastapi import FastAPI
from sqlalchemy.orm import Session, sessionmaker

from app.jobs import queue
from app.jobs.backfill import Backfiller
from app.jobs.local import Finished, LocalExecutor
from app.jobs.settings import JobSettings
from app.models import RunStatus
from app.settings import Settings

log = logging.getLogger(__name__)
#: Seconds between two heartbeats, and between two looks for vanished workers.
HEARTBEAT_S, RECOVER_S = 5.0, 30.0
#: Seconds the runs get to checkpoint and exit when the worker stops.
STOP_GRACE_S = 30.0
SERVER_STOPPED = "the server stopped while the run was running; resume it from its last checkpoint"


class Executor(Protocol):
    """What the worker needs of an executor (:class:`LocalExecutor`, ``RayExecutor``)."""

    name: str
    signals_runs: bool

    @property
    def active(self) -> int: ...

    def start(self, run_id: int, worker: str) -> None: ...

    def poll(self) -> list[Finished]: ...

    def request_stop(self) -> None: ...

    def wait(self, timeout_s: float) -> None: ...


def make_executor(settings: Settings, jobs: JobSettings) -> Executor:
    """The ``ray`` executor when ``ACV_RAY_ADDRESS`` is set, else the ``local`` one."""
    runs_dir = jobs.runs_root(settings)
    if jobs.ray_address:
        from app.jobs.ray_executor import RayExecutor

        return RayExecutor(
            address=jobs.ray_address, database_url=settings.sqlalchemy_url, runs_dir=runs_dir
        )
    return LocalExecutor(
        database_url=settings.sqlalchemy_url,
        runs_dir=runs_dir,
        split_lone_runs=jobs.splits_lone_runs,
    )


def make_backfiller(
    sessions: sessionmaker[Session], settings: Settings, jobs: JobSettings
) -> Backfiller | None:
    """The idle-time backfill, unless ``ACV_BACKFILL_S`` is 0."""
    if not jobs.backfill_s:
        return None
    return Backfiller(
        sessions,
        database_url=settings.sqlalchemy_url,
        runs_dir=jobs.runs_root(settings),
        every_s=jobs.backfill_s,
    )


class Worker:
    """Claims runs for one executor, at most ``slots`` at a time.

    Args:
        sessions: database sessions.
        executor: where the runs execute.
        slots: runs at the same time.
        poll_s: seconds between two looks at the queue.
        backfill: judges the unjudged checkpoints of ended runs while the worker is idle.
    """

    def __init__(
        self,
        sessions: sessionmaker[Session],
        executor: Executor,
        *,
        slots: int = 1,
        poll_s: float = 1.0,
        backfill: Backfiller | None = None,
    ) -> None:
        self.sessions, self.executor = sessions, executor
        self.slots, self.poll_s, self.backfill = slots, poll_s, backfill
        self.id = queue.new_worker_id()
        self._beat_at = self._recover_at = 0.0

    def run(self, stop: threading.Event, *, until_idle: bool = False) -> None:
        """Work until ``stop`` is set (or, with ``until_idle``, the queue and slots are empty);
        then stop the runs still going (they become ``interrupted``)."""
        queue.register(self.id, live=True)
        log.info(
            "worker %s (%s executor, %d slots) started", self.id, self.executor.name, self.slots
        )
        try:
            while not stop.is_set():
                claimed = self.tick()
                idle = not claimed and self.executor.active == 0
                if until_idle and idle:
                    break
                if self.backfill is not None:
                    self.backfill.tick(idle=idle)
                stop.wait(0 if claimed else self.poll_s)
        finally:
            self.shutdown()
            queue.register(self.id, live=False)

    def tick(self) -> bool:
        """One round of the loop; whether a run was claimed."""
        with self.sessions() as session:
            for ended in self.executor.poll():
                self._reap(session, ended)
            now = time.monotonic()
            if now >= self._recover_at:
                for run_id in queue.recover(session):
                    log.warning("run %d: its worker is gone; marked interrupted", run_id)
                self._recover_at = now + RECOVER_S
            if now >= self._beat_at:
                queue.heartbeat(session, worker=self.id)
                self._beat_at = now + HEARTBEAT_S
            return self._fill(session)

    def _fill(self, session: Session) -> bool:
        claimed = False
        while self.executor.active < self.slots:
            run_id = queue.claim_next(session, worker=self.id, executor=self.executor.name)
            if run_id is None:
                break
            claimed = True
            log.info("run %d: claimed by %s", run_id, self.id)
            try:
                self.executor.start(run_id, self.id)
            except Exception as exc:  # the run must not stay `running` without a process
                log.exception("run %d: could not be started", run_id)
                queue.finish(
                    session,
                    run_id=run_id,
                    worker=self.id,
                    status=RunStatus.FAILED,
                    error=f"could not start the run: {type(exc).__name__}: {exc}",
                )
        return claimed

    def _reap(self, session: Session, ended: Finished) -> None:
        error = ended.error or "the run process exited without reporting a result"
        if queue.finish(
            session, run_id=ended.run_id, worker=self.id, status=RunStatus.FAILED, error=error
        ):
            log.error("run %d failed: %s", ended.run_id, error)

    def shutdown(self, grace_s: float = STOP_GRACE_S) -> None:
        """Stop the runs of this worker; each checkpoints and becomes ``interrupted``."""
        if self.backfill is not None:
            self.backfill.stop()
        self.executor.request_stop()
        with self.sessions() as session:
            if not self.executor.signals_runs:
                queue.interrupt_worker_runs(session, worker=self.id, reason=SERVER_STOPPED)
            self.executor.wait(grace_s)
            # Runs that did not stop by themselves (killed after the grace period) can resume.
            queue.interrupt_worker_runs(session, worker=self.id, reason=SERVER_STOPPED)
            self.executor.poll()


class WorkerThread:
    """A :class:`Worker` on a daemon thread (the web server's local worker)."""

    def __init__(self, worker: Worker) -> None:
        self.worker = worker
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=worker.run, args=(self._stop,), name="acv-run-worker", daemon=True
        )

    def start(self) -> WorkerThread:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the worker and wait until its runs are stopped."""
        self._stop.set()
        self._thread.join()


def start_app_worker(app: FastAPI) -> WorkerThread | None:
    """Start the server's worker, unless ``ACV_RUN_WORKER`` is false.

    Job settings come from ``app.state.job_settings`` when set (tests), else the environment.
    """
    jobs: JobSettings = getattr(app.state, "job_settings", None) or JobSettings()
    app.state.job_settings = jobs
    if not jobs.run_worker:
        return None
    runtime = app.state.runtime
    worker = Worker(
        runtime.sessions,
        make_executor(runtime.settings, jobs),
        slots=jobs.worker_slots,
        poll_s=jobs.poll_s,
        backfill=make_backfiller(runtime.sessions, runtime.settings, jobs),
    )
    app.state.run_worker = worker
    return WorkerThread(worker).start()
