"""A run's state as rows: its metrics (one row per PPO update) and its saved checkpoints.

The run's executor writes them (:func:`record_update`, one transaction per update, with the
run's progress); pages and the API read them (:func:`metrics_rows`, :func:`checkpoint_steps`)
and never the run folder, which may live on another machine. Runs trained before these rows
existed are imported once from their folders (:func:`import_folder`, by the worker's
backfill).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

from sqlalchemy import delete, exists, insert, select, update
from sqlalchemy.orm import Session, sessionmaker

from app.db import writing
from app.models import Run, RunCheckpoint, RunMetric, RunStatus, utcnow
from app.runs.artefacts import checkpoint_steps as folder_checkpoints
from engine.errors import InputError
from engine.rl.logger import METRICS_FILE, read_metrics

log = logging.getLogger(__name__)

#: The largest step a 64-bit column holds.
_MAX_STEP = 2**63 - 1
#: Per-episode lists of a metrics row: kept in the run folder only.
EPISODE_KEYS = ("episode_returns", "episode_shaped_returns")


def scalar_metrics(row: dict[str, Any]) -> dict[str, Any]:
    """A metrics row as stored: scalars only, NaN and infinities as null."""
    return {
        k: None if isinstance(v, float) and not math.isfinite(v) else v
        for k, v in row.items()
        if k not in EPISODE_KEYS and (v is None or isinstance(v, int | float))
    }


def record_update(
    session: Session, *, run_id: int, owner: tuple[Any, ...], row: dict[str, Any], saved: bool
) -> bool:
    """Store one update of a run in one transaction: its progress and latest metrics on the
    run, its metrics row, and its checkpoint when one was ``saved`` at this step. Rows at or
    past this step from an earlier attempt (a resumed run trains them again) are replaced.

    Args:
        owner: the conditions under which the run is still the caller's to run.

    Returns:
        False (and nothing stored) when the run is no longer the caller's.
    """
    metrics, step = scalar_metrics(row), int(row["timesteps"])
    with writing(session):
        taken = session.execute(
            update(Run)
            .where(*owner)
            .values(progress=step, metrics=metrics, heartbeat_at=utcnow())
            .execution_options(synchronize_session=False)
        )
        if taken.rowcount != 1:  # type: ignore[attr-defined]
            return False
        session.execute(
            delete(RunMetric).where(RunMetric.run_id == run_id, RunMetric.timesteps >= step)
        )
        session.execute(
            delete(RunCheckpoint).where(RunCheckpoint.run_id == run_id, RunCheckpoint.step >= step)
        )
        session.execute(insert(RunMetric).values(run_id=run_id, timesteps=step, row=metrics))
        if saved:
            session.execute(insert(RunCheckpoint).values(run_id=run_id, step=step))
    return True


def metrics_rows(session: Session, *, run_id: int, after: int = -1) -> list[dict[str, Any]]:
    """The run's metrics rows with ``timesteps`` above ``after``, in order."""
    after = min(after, _MAX_STEP)  # a larger ``after`` asks for nothing, and overflows SQLite
    return list(
        session.scalars(
            select(RunMetric.row)
            .where(RunMetric.run_id == run_id, RunMetric.timesteps > after)
            .order_by(RunMetric.timesteps)
        )
    )


def checkpoint_steps(session: Session, *, run_id: int) -> list[int]:
    """The timesteps of the run's saved checkpoints, increasing."""
    return list(
        session.scalars(
            select(RunCheckpoint.step)
            .where(RunCheckpoint.run_id == run_id)
            .order_by(RunCheckpoint.step)
        )
    )


def unimported(session: Session) -> list[int]:
    """Runs that ended or stopped with no metrics row stored: trained before run state was
    stored in the database (their folders still hold it)."""
    has_rows = exists().where(RunMetric.run_id == Run.id)
    return list(
        session.scalars(
            select(Run.id).where(Run.progress > 0, ~has_rows, Run.status != RunStatus.RUNNING)
        )
    )


def import_folder(session: Session, *, run_id: int, out: Path) -> int:
    """Store the metrics rows and checkpoints of ``out`` (the run folder of ``run_id``) as
    rows, once: a run that has rows already is left alone. Returns the rows stored."""
    try:
        found = read_metrics(out) if (out / METRICS_FILE).is_file() else []
    except InputError as exc:  # a damaged file: its run keeps no rows, and says why in the log
        log.warning("run %d: metrics not imported: %s", run_id, exc)
        found = []
    rows = {int(row["timesteps"]): scalar_metrics(row) for row in found}
    steps = folder_checkpoints(out)
    with writing(session):
        if session.scalar(select(exists().where(RunMetric.run_id == run_id))):
            return 0
        for timesteps, row in rows.items():
            session.add(RunMetric(run_id=run_id, timesteps=timesteps, row=row))
        for step in steps:
            session.add(RunCheckpoint(run_id=run_id, step=step))
    return len(rows) + len(steps)


def import_folders(sessions: sessionmaker[Session], *, runs_root: Path) -> int:
    """:func:`import_folder` for every run of :func:`unimported`; returns the rows stored."""
    with sessions() as session:
        todo = unimported(session)
    stored = 0
    for run_id in todo:
        with sessions() as session:
            stored += import_folder(session, run_id=run_id, out=runs_root / str(run_id))
    return stored
