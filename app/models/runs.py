"""Training runs, experiments and what their executors store (app/runs, app/jobs)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    text,
)
from sqlalchemy.orm import Mapped, mapped_column

from app.models.base import (
    Base,
    ExperimentRole,
    RunStatus,
    enum_type,
    status_check,
    utcnow,
)
from engine.rl.config import Algo
from engine.teachers import Teacher

#: The rows of ``ix_runs_shared``: runs experiments share.
SHARED = text("config_digest IS NOT NULL")


class Run(Base):
    """A training run of a study, and its place in the job queue (see :mod:`app.jobs`).

    ``advice`` is the ``acv.tree/1`` document the run trains with (a finished participant's
    tree or a simulated teacher's, frozen when the run is created) or NULL. A run on pooled
    advice lists its participants' trees in ``advice_pool`` (``{"participant_id", "tree"}``,
    by participant id), has no ``participant_id`` nor ``teacher``, and its ``advice`` is the
    pooled verdict (:func:`engine.pooling.pooled_tree`). ``config`` is the
    whole :class:`engine.rl.config.TrainConfig`. ``worker`` names the worker that claimed the
    run (``host:pid:nonce``) and ``heartbeat_at`` when it last showed signs of life.
    """

    __tablename__ = "runs"
    __table_args__ = (
        status_check(RunStatus),
        CheckConstraint("participant_id IS NULL OR teacher IS NULL", name="one_advice_source"),
        CheckConstraint("timesteps > 0 AND n_envs > 0 AND progress >= 0", name="budget"),
        # One shared run per study, config and seed: concurrent experiments take the same one
        Index(
            "ix_runs_shared",
            "study_id",
            "config_digest",
            "seed",
            unique=True,
            sqlite_where=SHARED,
            postgresql_where=SHARED,
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    participant_id: Mapped[int | None] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), default=None
    )
    teacher: Mapped[Teacher | None] = mapped_column(enum_type(Teacher), default=None)
    algo: Mapped[Algo] = mapped_column(enum_type(Algo))
    timesteps: Mapped[int] = mapped_column(BigInteger)
    seed: Mapped[int] = mapped_column(BigInteger)
    n_envs: Mapped[int] = mapped_column(Integer)
    config: Mapped[dict] = mapped_column(JSON)
    advice: Mapped[dict | None] = mapped_column(JSON, default=None)
    advice_pool: Mapped[list | None] = mapped_column(JSON, default=None)
    status: Mapped[RunStatus] = mapped_column(
        enum_type(RunStatus), default=RunStatus.QUEUED, index=True
    )
    resume: Mapped[bool] = mapped_column(Boolean, default=False)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    executor: Mapped[str | None] = mapped_column(String(16), default=None)
    worker: Mapped[str | None] = mapped_column(String(200), default=None)
    progress: Mapped[int] = mapped_column(BigInteger, default=0)
    metrics: Mapped[dict | None] = mapped_column(JSON, default=None)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: Set on the one run that experiments share as their baseline or pilot at this study,
    #: config and seed (a ``ppo`` run naming advice): the SHA-256 of ``config``
    #: (:func:`app.runs.shared.config_digest`); NULL on every other run, and cleared when a
    #: failed or cancelled run gives its place to a new one.
    config_digest: Mapped[str | None] = mapped_column(String(64), default=None)


class Experiment(Base):
    """One advice source, algorithm, env and budget trained on several seeds, with its
    matched no-advice baseline (the same seeds) and pilot runs (seeds of their own).

    ``spec`` is the request its advised runs were created from, less the seed (``/api/runs``'s
    body); ``seeds`` the evaluation seeds, ``pilot_seeds`` the pilot runs' seeds (disjoint).
    Its runs are listed in ``experiment_runs``; a baseline or pilot run may be shared by
    several experiments (the same study, config and seed).
    """

    __tablename__ = "experiments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    spec: Mapped[dict] = mapped_column(JSON)
    seeds: Mapped[list] = mapped_column(JSON)
    pilot_seeds: Mapped[list] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ExperimentRun(Base):
    """A run's part in an experiment (:class:`ExperimentRole`)."""

    __tablename__ = "experiment_runs"
    __table_args__ = (
        CheckConstraint(
            "role IN (" + ", ".join(f"'{r.value}'" for r in ExperimentRole) + ")", name="role"
        ),
    )

    experiment_id: Mapped[int] = mapped_column(
        ForeignKey("experiments.id", ondelete="CASCADE"), primary_key=True
    )
    run_id: Mapped[int] = mapped_column(
        ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True, index=True
    )
    role: Mapped[ExperimentRole] = mapped_column(enum_type(ExperimentRole, length=8))


class CheckpointArtefact(Base):
    """What the executor computed at one checkpoint of a run; written once, then only read.

    ``payload`` is :meth:`engine.rl.report.CheckpointReport.to_json`: the Agent Preference
    Tree of every judge, its conformance to the run's advice tree, and the per-candidate table.
    A checkpoint without a row is still being computed ("pending").
    """

    __tablename__ = "checkpoint_artefacts"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    step: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    payload: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class RunMetric(Base):
    """One metrics row of a run (one per PPO update), as its executor reported it: scalars
    only (:func:`app.runs.run_state.scalar_metrics`). Pages and the API read these, never the
    run folder's ``metrics.jsonl``."""

    __tablename__ = "run_metrics"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    timesteps: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    row: Mapped[dict] = mapped_column(JSON)


class RunCheckpoint(Base):
    """A checkpoint a run's executor saved (its file is ``checkpoints/step_<step>.pt`` in the
    run folder, which only executors read)."""

    __tablename__ = "run_checkpoints"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    step: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    saved_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
