"""The ``runs`` table as a job queue: claims, heartbeats, final states and recovery.

Every transition is one conditional ``UPDATE`` whose row count says whether it happened, so
it is atomic on SQLite (one writer at a time) and on PostgreSQL (a second updater of the row
waits for the first, then re-checks the ``WHERE`` clause): two workers never take the same
run, and a process that lost its run (cancelled, interrupted by a restart) cannot overwrite
the state someone else set.

A worker is named ``host:pid:nonce``. A ``running`` run whose worker is gone (a dead process
on this host, or no heartbeat for :data:`STALE_S` seconds) becomes ``interrupted``.
"""

from __future__ import annotations

import os
import secrets
import socket
from collections.abc import Callable
from datetime import timedelta
from typing import Any, cast

from sqlalchemy import CursorResult, func, select, update
from sqlalchemy.orm import Session

from app.db import writing
from app.models import Run, RunStatus, as_utc, utcnow

#: Seconds without a heartbeat after which a running run's worker counts as gone.
STALE_S = 60.0
#: Queued runs looked at per claim attempt (others may take some of them meanwhile).
CLAIM_BATCH = 8
INTERRUPTED = "the worker running it stopped; resume it from its last checkpoint"
_LIVE_WORKERS: set[str] = set()  # workers of this process that are running


def new_worker_id() -> str:
    """A unique name for a worker of this process: ``host:pid:nonce``."""
    return f"{socket.gethostname()}:{os.getpid()}:{secrets.token_hex(4)}"


def register(worker: str, live: bool) -> None:
    """Mark a worker of this process as live (or gone), for :func:`worker_alive`."""
    (_LIVE_WORKERS.add if live else _LIVE_WORKERS.discard)(worker)


def worker_alive(worker: str) -> bool | None:
    """Whether a worker is alive, when this host can tell; ``None`` for other hosts."""
    host, _, rest = worker.partition(":")
    pid_text = rest.partition(":")[0]
    if host != socket.gethostname() or not pid_text.isdigit():
        return None
    if int(pid_text) == os.getpid():
        return worker in _LIVE_WORKERS
    try:
        os.kill(int(pid_text), 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process with that pid: alive
        return True
    return True


def update_if(session: Session, where: tuple, **values: Any) -> bool:
    """One conditional update in its own transaction; whether it changed a row."""
    with writing(session):
        result = cast(
            CursorResult[Any],
            session.execute(
                update(Run)
                .where(*where)
                .values(**values)
                .execution_options(synchronize_session=False)
            ),
        )
    return result.rowcount == 1


def claim_next(session: Session, *, worker: str, executor: str) -> int | None:
    """Take the oldest queued run for ``worker``; its id, or None when the queue is empty."""
    queued = list(
        session.scalars(
            select(Run.id).where(Run.status == RunStatus.QUEUED).order_by(Run.id).limit(CLAIM_BATCH)
        )
    )
    session.rollback()  # end the read transaction before writing
    now = utcnow()
    for run_id in queued:
        if update_if(
            session,
            (Run.id == run_id, Run.status == RunStatus.QUEUED),
            status=RunStatus.RUNNING,
            worker=worker,
            executor=executor,
            started_at=now,
            heartbeat_at=now,
            error=None,
        ):
            return run_id
    return None


def heartbeat(session: Session, *, worker: str) -> None:
    """Tell the others that ``worker`` still looks after its running runs."""
    with writing(session):
        session.execute(
            update(Run)
            .where(Run.worker == worker, Run.status == RunStatus.RUNNING)
            .values(heartbeat_at=utcnow())
            .execution_options(synchronize_session=False)
        )


def stop_reason(session: Session, *, run_id: int, worker: str) -> str | None:
    """``cancel`` when a cancel was asked, ``lost`` when the run is no longer ours, else None."""
    row = session.execute(
        select(Run.status, Run.worker, Run.cancel_requested).where(Run.id == run_id)
    ).one_or_none()
    session.rollback()
    if row is None or row.status != RunStatus.RUNNING or row.worker != worker:
        return "lost"
    return "cancel" if row.cancel_requested else None


def running_besides(session: Session, *, run_id: int) -> int:
    """How many runs other than ``run_id`` are running now, on any worker."""
    count = session.scalar(
        select(func.count()).where(Run.status == RunStatus.RUNNING, Run.id != run_id)
    )
    session.rollback()
    return int(count or 0)


def finish(
    session: Session, *, run_id: int, worker: str, status: str, error: str | None = None
) -> bool:
    """Move a run this worker is running to its final ``status`` (or ``interrupted``)."""
    finished_at = None if status == RunStatus.INTERRUPTED else utcnow()
    return update_if(
        session, ours(run_id, worker), status=status, error=error, finished_at=finished_at
    )


def interrupt_worker_runs(session: Session, *, worker: str, reason: str = INTERRUPTED) -> int:
    """Mark every run ``worker`` is running as ``interrupted``; how many there were."""
    with writing(session):
        result = cast(
            CursorResult[Any],
            session.execute(
                update(Run)
                .where(Run.worker == worker, Run.status == RunStatus.RUNNING)
                .values(status=RunStatus.INTERRUPTED, error=reason)
                .execution_options(synchronize_session=False)
            ),
        )
    return result.rowcount


def recover(
    session: Session,
    *,
    alive: Callable[[str], bool | None] = worker_alive,
    stale_s: float = STALE_S,
) -> list[int]:
    """Mark running runs whose worker is gone as ``interrupted``; returns their ids.

    A worker is gone when ``alive`` says so, or (where it cannot tell) when the run had no
    heartbeat for ``stale_s`` seconds.
    """
    rows = session.execute(
        select(Run.id, Run.worker, Run.heartbeat_at).where(Run.status == RunStatus.RUNNING)
    ).all()
    session.rollback()
    cutoff = utcnow() - timedelta(seconds=stale_s)
    gone = [
        (rid, w)
        for rid, w, beat in rows
        if w is None
        or alive(w) is False
        or (alive(w) is None and (beat is None or as_utc(beat) < cutoff))
    ]
    return [
        rid
        for rid, w in gone
        if update_if(
            session,
            (
                Run.id == rid,
                Run.status == RunStatus.RUNNING,
                Run.worker.is_(None) if w is None else Run.worker == w,
            ),
            status=RunStatus.INTERRUPTED,
            error=INTERRUPTED,
        )
    ]


def ours(run_id: int, worker: str) -> tuple:
    """The conditions under which run ``run_id`` is still ``worker``'s to run."""
    return Run.id == run_id, Run.worker == worker, Run.status == RunStatus.RUNNING
