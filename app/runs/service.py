"""Training runs: creation (with their advice), look-ups, cancel and resume.

A run belongs to a study. Its advice is frozen when it is created: a finished participant's
Human Preference Tree, several finished participants' trees pooled (:mod:`app.runs.pools`: by
the plain mean, or weighted by reliability),
a simulated teacher's tree over the same bracket (the study's candidates and first round), or
none (``ppo`` only). A ``ppo`` run may still name advice: it
trains without it, and its Agent Preference Tree is compared with that tree (the baseline of
a ``bipars-em`` run on the same advice). Workers (:mod:`app.jobs`) execute queued runs.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.jobs.queue import update_if
from app.models import Run, RunStatus, utcnow
from app.runs import advice, pools, run_state, shared
from app.runs.imported import is_imported
from app.runs.spec import ParticipantAdvice, RunSpec, TeacherAdvice
from app.studies.service import get_ready_study
from engine.errors import InputError
from engine.rl.config import TrainConfig
from engine.treefile import TreeDocument, tree_from_json, tree_to_json

RESUMABLE: tuple[RunStatus, ...] = (RunStatus.INTERRUPTED, RunStatus.FAILED, RunStatus.CANCELLED)
FINAL: tuple[RunStatus, ...] = (RunStatus.SUCCEEDED, RunStatus.FAILED, RunStatus.CANCELLED)
MAX_TIMESTEPS = 100_000_000
#: Checkpoints a run writes when the request does not say how often.
DEFAULT_CHECKPOINTS = 10


def create_run(session: Session, *, spec: RunSpec, reuse: bool = False) -> Run:
    """Validate and queue a new run (a ``ppo`` run that names advice is shared by experiments
    while it is the first at its study, config and seed: :mod:`app.runs.shared`).

    Args:
        reuse: an experiment's baseline or pilot: the shared run of the same study, config and
            seed when there is one, instead of a new run.

    Raises:
        InputError: bad parameters, a bad pool, or an advised algo without advice.
        NotFoundError: no such study or participant (or not in this study).
        ConflictError: the study is not ready, a participant has not finished or is excluded,
            or a reliability-weighted pool's reliabilities are all 0.
    """
    study = get_ready_study(session, study_id=spec.study_id)
    _check_timesteps(spec)
    config = train_config(spec, env_id=study.env_id)
    pooled, tree = advice.resolve(
        session, spec.advice, study_id=spec.study_id, tree_options=config.tree_options()
    )
    if tree is None and config.uses_advice:
        raise InputError(
            f"algo {spec.algo} trains with advice: give participant_id, participant_ids or teacher"
        )
    if pooled is not None and pooled.weights is not None:  # F trains with the verdict's weights
        config = replace(config, pool_weights=pooled.weights)
    pool = None if pooled is None else pooled.members
    return _queue(session, spec, config, pool, tree, reuse=reuse)


def _check_timesteps(spec: RunSpec) -> None:
    if not 0 < spec.timesteps <= MAX_TIMESTEPS:
        raise InputError(f"timesteps must be in 1..{MAX_TIMESTEPS}, got {spec.timesteps}")


def _queue(
    session: Session,
    spec: RunSpec,
    config: TrainConfig,
    pool: pools.Pool | None,
    tree: TreeDocument | None,
    *,
    reuse: bool,
) -> Run:
    """Store the run, queued (a worker picks it up), or find the shared one (``reuse``)."""
    source = spec.advice
    values: dict[str, Any] = dict(
        study_id=spec.study_id,
        participant_id=source.participant_id if isinstance(source, ParticipantAdvice) else None,
        teacher=source.teacher if isinstance(source, TeacherAdvice) else None,
        advice_pool=pool,
        algo=spec.algo,
        timesteps=spec.timesteps,
        seed=spec.seed,
        n_envs=spec.n_envs,
        config=config.to_json(),
        advice=None if tree is None else tree_to_json(tree),
        status=RunStatus.QUEUED,
        resume=False,
        cancel_requested=False,
        progress=0,
    )
    if shared.shareable(values):
        return shared.store(session, values, reuse=reuse)
    run = Run(**values)
    with writing(session):
        session.add(run)
    return run


def train_config(spec: RunSpec, *, env_id: str) -> TrainConfig:
    """The configuration of the run ``spec`` asks for on ``env_id``; by default about
    :data:`DEFAULT_CHECKPOINTS` checkpoints."""
    options: dict[str, Any] = {k: v for k, v in spec.options.items() if k != "checkpoint_every"}
    base = TrainConfig(
        algo=spec.algo,
        env_id=env_id,
        total_timesteps=spec.timesteps,
        seed=spec.seed,
        n_envs=spec.n_envs,
        **options,
    )
    every = spec.options.get("checkpoint_every") or base.batch_size * max(
        1, base.num_updates // DEFAULT_CHECKPOINTS
    )
    return TrainConfig(**{**base.to_json(), "checkpoint_every": every})


def get_run(session: Session, *, run_id: int) -> Run:
    """The run, or :class:`NotFoundError`."""
    run = session.get(Run, run_id)
    if run is None:
        raise NotFoundError(f"run {run_id} not found")
    return run


def list_runs(session: Session, *, study_id: int | None = None) -> list[Run]:
    """Runs (of one study, or all), newest first."""
    query = select(Run).order_by(Run.id.desc())
    if study_id is not None:
        query = query.where(Run.study_id == study_id)
    return list(session.scalars(query))


def same_advice_runs(session: Session, *, run: Run) -> list[Run]:
    """The runs of ``run``'s study with the same advice source (itself included), oldest
    first: what the multi-run comparison puts side by side."""
    source = (
        Run.participant_id == run.participant_id
        if run.participant_id is not None
        else Run.teacher == run.teacher
        if run.teacher is not None
        else Run.participant_id.is_(None) & Run.teacher.is_(None)
    )
    found = session.scalars(
        select(Run).where(Run.study_id == run.study_id, source).order_by(Run.id)
    )
    # a pool is compared in Python: JSON has no equality in PostgreSQL
    return [r for r in found if pools.same_pool(r, run)]


def advice_of(run: Run) -> TreeDocument:
    """The run's advice tree (its Human Preference Tree in comparisons).

    Raises:
        ConflictError: the run has no advice to compare with.
    """
    if run.advice is None:
        raise ConflictError(
            f"run {run.id} has no advice tree to compare with (it was "
            "created without participant_id, participant_ids or teacher)"
        )
    return tree_from_json(run.advice)


def advice_label(run: Run) -> str:
    """Who gave the advice, for people: ``participant #3``, ``3 participants pooled (#1, #2,
    #4)``, ``teacher standing``, ``none``."""
    if (ids := pools.members(run)) is not None:
        return pools.pool_label(ids, weighted=pools.weighting_of(run) == "reliability")
    if run.participant_id is not None:
        return f"participant #{run.participant_id}"
    return f"teacher {run.teacher}" if run.teacher is not None else "none"


def cancel_run(session: Session, *, run_id: int) -> Run:
    """Cancel a queued run now, or ask a running one to stop (it checkpoints first).

    Raises:
        ConflictError: the run has already ended.
    """
    get_run(session, run_id=run_id)
    if not update_if(
        session,
        (Run.id == run_id, Run.status.in_((RunStatus.QUEUED, RunStatus.INTERRUPTED))),
        status=RunStatus.CANCELLED,
        finished_at=utcnow(),
    ) and not update_if(
        session, (Run.id == run_id, Run.status == RunStatus.RUNNING), cancel_requested=True
    ):
        raise ConflictError(f"run {run_id} has already ended")
    return _fresh(session, run_id)


def resume_run(session: Session, *, run_id: int) -> Run:
    """Queue an interrupted, failed or cancelled run again, to continue from its latest
    checkpoint (an imported policy: to be judged again).

    Raises:
        ConflictError: the run is queued, running or succeeded, or has no checkpoint.
    """
    run = get_run(session, run_id=run_id)
    if run.status not in RESUMABLE:
        raise ConflictError(
            f"run {run_id} is {run.status}; only {', '.join(RESUMABLE)} runs can be resumed"
        )
    if not run_state.checkpoint_steps(session, run_id=run_id) and not is_imported(run):
        raise ConflictError(f"run {run_id} has no checkpoint to resume from")
    if not update_if(
        session,
        (Run.id == run_id, Run.status == run.status),
        status=RunStatus.QUEUED,
        resume=True,
        cancel_requested=False,
        error=None,
        finished_at=None,
        worker=None,
    ):
        raise ConflictError(f"run {run_id} changed meanwhile; try again")
    return _fresh(session, run_id)


def _fresh(session: Session, run_id: int) -> Run:
    session.expire_all()
    return get_run(session, run_id=run_id)
