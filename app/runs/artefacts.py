"""Checkpoint artefacts: what a run's executor computes once per checkpoint, and the web reads.

When a run writes a checkpoint, its executor (a local process or a Ray task, where torch,
MuJoCo and the run folder are) computes that checkpoint's report: every judge's Agent
Preference Tree, its conformance to the run's advice tree, and the per-candidate table
(:func:`engine.rl.report.checkpoint_report`). It stores the report as one immutable
:class:`app.models.CheckpointArtefact` row. Web processes only read these rows; a checkpoint
without a row is *pending* (HTTP 202). A checkpoint that cannot be judged (a corrupt file) gets
a row holding the reason, so that readers answer with that reason (HTTP 422) instead of
waiting for ever. Checkpoints of ended runs without a row (the one a stop writes, runs from
before artefacts) get theirs from :func:`backfill`, which an idle worker starts by itself
(:mod:`app.jobs.backfill`) and ``acv worker --backfill`` runs on demand; never from a request.

Checkpoint steps are listed from file names (:func:`checkpoint_steps`), so that listing them
imports neither torch nor MuJoCo.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from app.core.errors import PendingError
from app.models import CheckpointArtefact, Run, RunStatus
from engine.errors import InputError
from engine.treefile import TreeDocument, tree_from_json

if TYPE_CHECKING:  # torch loads with the report, in executor processes only
    from engine.rl.report import CheckpointReport

log = logging.getLogger(__name__)
#: ``checkpoints/step_<timesteps>.pt``, as :mod:`engine.rl.checkpoint` writes them.
_CHECKPOINT = re.compile(r"^step_(\d+)\.pt$")
#: Statuses of runs whose executor has gone: their missing artefacts are the backfill's.
ENDED = (RunStatus.SUCCEEDED, RunStatus.FAILED, RunStatus.CANCELLED, RunStatus.INTERRUPTED)
#: The key of an artefact that records why its checkpoint could not be judged.
FAILURE = "error"
#: The key of a pooled run's per-participant conformance (absent for other runs).
ADVISORS = "advisors"


def checkpoint_file(out: Path, step: int) -> Path:
    """Where the run directory ``out`` keeps its checkpoint at ``step`` (no torch import)."""
    return out / "checkpoints" / f"step_{step}.pt"


def checkpoint_steps(out: Path) -> list[int]:
    """The timesteps of the run directory's checkpoints, increasing (no torch import)."""
    folder = out / "checkpoints"
    if not folder.is_dir():
        return []
    return sorted(int(m.group(1)) for p in folder.iterdir() if (m := _CHECKPOINT.match(p.name)))


def payload(session: Session, *, run_id: int, step: int) -> dict[str, Any]:
    """The stored report of run ``run_id`` at ``step`` (``acv.checkpoint/1``).

    Raises:
        PendingError: not computed yet (the executor or the backfill will).
        InputError: the checkpoint could not be judged (the stored reason).
    """
    row = session.get(CheckpointArtefact, (run_id, step))
    if row is None:
        raise PendingError(
            f"the agent trees of run {run_id} at checkpoint {step} are being "
            "computed; try again shortly"
        )
    if FAILURE in row.payload:
        raise InputError(row.payload[FAILURE])
    return row.payload


def judged(body: dict[str, Any]) -> bool:
    """Whether a stored artefact is a report, not the reason a checkpoint could not be judged."""
    return FAILURE not in body


def payloads(session: Session, *, run_id: int) -> dict[int, dict[str, Any]]:
    """Every stored report of the run: step -> payload, increasing steps."""
    rows = session.execute(
        select(CheckpointArtefact.step, CheckpointArtefact.payload)
        .where(CheckpointArtefact.run_id == run_id)
        .order_by(CheckpointArtefact.step)
    )
    return {step: body for step, body in rows}


def computed_steps(session: Session, *, run_id: int) -> set[int]:
    """The steps of the run that have a stored report."""
    return set(
        session.scalars(select(CheckpointArtefact.step).where(CheckpointArtefact.run_id == run_id))
    )


def compute(
    out: Path, step: int, advice: TreeDocument, pool: list[dict[str, Any]] | None = None
) -> dict[str, Any]:
    """The report of checkpoint ``step`` as JSON; loads torch and builds the env (executor
    processes only).

    For pooled advice (``pool``: ``runs.advice_pool``) the body also holds, under
    :data:`ADVISORS`, each pooled participant's tree judged by every judge's agent tree:
    ``[{"participant_id", "judges": {judge: conformance JSON}}]`` (``advice`` is then the
    pooled verdict, which the body's own conformance is to).
    """
    from engine.rl.report import checkpoint_report

    return report_json(checkpoint_report(out, step, advice=advice), pool)


def report_json(report: CheckpointReport, pool: list[dict[str, Any]] | None) -> dict[str, Any]:
    """A checkpoint's report as stored, with each pooled participant's conformance (see
    :func:`compute`); also the body of an imported policy's report."""
    from engine.rl.report import members_conformance

    body = report.to_json()
    if pool:
        per_member = members_conformance(report, [tree_from_json(m["tree"]) for m in pool])
        body[ADVISORS] = [
            {
                "participant_id": m["participant_id"],
                "judges": {j: c.to_json() for j, c in by.items()},
            }
            for m, by in zip(pool, per_member, strict=True)
        ]
    return body


def store(session: Session, *, run_id: int, step: int, body: dict[str, Any]) -> bool:
    """Insert the report unless one exists (artefacts are immutable); True if inserted."""
    if session.get(CheckpointArtefact, (run_id, step)) is not None:
        return False
    session.add(CheckpointArtefact(run_id=run_id, step=step, payload=body))
    try:
        session.commit()
    except IntegrityError:  # another process stored it first
        session.rollback()
        return False
    return True


def record(
    sessions: sessionmaker[Session],
    *,
    run_id: int,
    advice: dict[str, Any],
    out: Path,
    step: int,
    pool: list[dict[str, Any]] | None = None,
) -> bool:
    """Compute and store the report of one checkpoint, unless stored already; a checkpoint
    that cannot be judged (:class:`InputError`, e.g. a corrupt file) stores the reason.
    ``pool`` is the run's ``advice_pool`` (pooled advice only; see :func:`compute`)."""
    with sessions() as session:
        if session.get(CheckpointArtefact, (run_id, step)) is not None:
            return False
    try:
        body = compute(out, step, tree_from_json(advice), pool)
    except InputError as exc:
        log.warning("run %d, checkpoint %d cannot be judged: %s", run_id, step, exc)
        body = {FAILURE: str(exc)}
    with sessions() as session:
        return store(session, run_id=run_id, step=step, body=body)


def missing(session: Session, *, runs_root: Path) -> list[tuple[int, int]]:
    """(run id, step) of ended runs' checkpoints without a report, oldest run first."""
    ended = session.execute(
        select(Run.id).where(Run.status.in_(ENDED), Run.advice.is_not(None)).order_by(Run.id)
    )
    todo = []
    for (run_id,) in ended:
        have = computed_steps(session, run_id=run_id)
        todo += [(run_id, s) for s in checkpoint_steps(runs_root / str(run_id)) if s not in have]
    return todo


def backfill(sessions: sessionmaker[Session], *, runs_root: Path, limit: int | None = None) -> int:
    """Compute the missing reports of ended runs (at most ``limit``); returns how many were
    stored. A checkpoint that cannot be judged stores the reason (see :func:`record`)."""
    with sessions() as session:
        todo = missing(session, runs_root=runs_root)[:limit]
        advice = {
            r.id: (r.advice, r.advice_pool)
            for r in session.scalars(select(Run).where(Run.id.in_({run_id for run_id, _ in todo})))
            if r.advice
        }
    done = 0
    for run_id, step in todo:
        if run_id not in advice:  # a JSON null, which `IS NOT NULL` lets through: no advice
            continue
        tree, pool = advice[run_id]
        done += record(
            sessions,
            run_id=run_id,
            advice=tree,
            out=runs_root / str(run_id),
            step=step,
            pool=pool,
        )
    return done
