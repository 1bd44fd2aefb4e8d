"""Database tables (SQLAlchemy 2 declarative). The schema itself comes from ``migrations/``.

A study owns its candidates (ids ``0 .. N-1``, as in ``acv.tree/1``) and its first-round
bracket; each participant plays the whole bracket on their own. A match row exists once both
of its players are known, and holds at most one label: ``labels.match_id`` is UNIQUE, so the
database itself refuses a second decision of a match.
"""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    ForeignKeyConstraint,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, validates

STUDY_STATUSES = ("preparing", "ready", "failed")
RUN_STATUSES = ("queued", "running", "succeeded", "failed", "cancelled", "interrupted")

#: Deterministic constraint names, so that migrations can refer to them on every backend.
NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_N_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utcnow() -> datetime:
    return datetime.now(UTC)


def as_utc(moment: datetime) -> datetime:
    """A stored time as an aware UTC datetime (SQLite returns them naive)."""
    return moment if moment.tzinfo else moment.replace(tzinfo=UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


class Study(Base):
    """A labelling study: env, candidate count, seeding parameters and instructions."""

    __tablename__ = "studies"
    __table_args__ = (
        CheckConstraint("n_candidates >= 2 AND n_candidates <= 128", name="n_candidates"),
        CheckConstraint("p >= 0 AND p <= 1", name="p"),
        CheckConstraint("status IN ('preparing', 'ready', 'failed')", name="status"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    env_id: Mapped[str] = mapped_column(String(100))
    n_candidates: Mapped[int] = mapped_column(Integer)
    p: Mapped[float] = mapped_column(Float)
    seed: Mapped[int] = mapped_column(BigInteger)
    sampling: Mapped[str] = mapped_column(String(16))
    instructions: Mapped[str] = mapped_column(Text)
    status: Mapped[str] = mapped_column(String(16), default="preparing")
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Candidate(Base):
    """A candidate state of a study: enough to restore it, its reward and its images.

    ``qpos`` and ``qvel`` are JSON lists of floats (exact: JSON keeps ``repr`` digits); the
    image paths are relative to the data dir.
    """

    __tablename__ = "candidates"

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True)
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    qpos: Mapped[list[float]] = mapped_column(JSON)
    qvel: Mapped[list[float]] = mapped_column(JSON)
    env_reward: Mapped[float] = mapped_column(Float)
    image_path: Mapped[str] = mapped_column(String(255))
    thumb_path: Mapped[str] = mapped_column(String(255))


class BracketSlot(Base):
    """One slot of a study's first round, in bracket order: ``b`` is NULL for a bye."""

    __tablename__ = "bracket_slots"
    __table_args__ = (
        ForeignKeyConstraint(["study_id", "a"], ["candidates.study_id", "candidates.id"],
                             ondelete="CASCADE"),
        ForeignKeyConstraint(["study_id", "b"], ["candidates.study_id", "candidates.id"],
                             ondelete="CASCADE"),
    )

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True)
    slot: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int | None] = mapped_column(Integer, default=None)


def token_digest(token: str) -> str:
    """SHA-256 of an invite token (hex): what participants are looked up by."""
    return hashlib.sha256(token.encode()).hexdigest()


class Participant(Base):
    """Someone labelling a study's bracket, known only by their invite token.

    Requests are matched by ``token_hash`` and then the token itself is compared in
    constant time (:func:`app.services.auth.participant_by_token`): an index lookup's timing
    can tell an attacker about the hash of their guess, never about a real token.
    """

    __tablename__ = "participants"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    token: Mapped[str] = mapped_column(String(64), unique=True)
    token_hash: Mapped[str] = mapped_column(String(64), index=True, unique=True)
    name: Mapped[str | None] = mapped_column(String(200), default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    last_active_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True),
                                                            default=None)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)

    @validates("token")
    def _hash_token(self, _key: str, token: str) -> str:
        self.token_hash = token_digest(token)
        return token


class Match(Base):
    """A match of one participant's bracket whose two players are known."""

    __tablename__ = "matches"
    __table_args__ = (
        UniqueConstraint("participant_id", "round", "slot"),
        CheckConstraint("a <> b", name="distinct_players"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"))
    round: Mapped[int] = mapped_column(Integer)
    slot: Mapped[int] = mapped_column(Integer)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Label(Base):
    """A participant's decision of a match; at most one per match (UNIQUE ``match_id``)."""

    __tablename__ = "labels"
    __table_args__ = (CheckConstraint("response_ms >= 0", name="response_ms"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    match_id: Mapped[int] = mapped_column(
        ForeignKey("matches.id", ondelete="CASCADE"), unique=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True)
    winner: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)


class Run(Base):
    """A training run of a study, and its place in the job queue (see :mod:`app.jobs`).

    ``advice`` is the ``acv.tree/1`` document the run trains with (a finished participant's
    tree or a simulated teacher's, frozen when the run is created) or NULL; ``config`` is the
    whole :class:`engine.rl.config.TrainConfig`. ``worker`` names the worker that claimed the
    run (``host:pid:nonce``) and ``heartbeat_at`` when it last showed signs of life.
    """

    __tablename__ = "runs"
    __table_args__ = (
        CheckConstraint("status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled', "
                        "'interrupted')", name="status"),
        CheckConstraint("participant_id IS NULL OR teacher IS NULL", name="one_advice_source"),
        CheckConstraint("timesteps > 0 AND n_envs > 0 AND progress >= 0", name="budget"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    participant_id: Mapped[int | None] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), default=None)
    teacher: Mapped[str | None] = mapped_column(String(16), default=None)
    algo: Mapped[str] = mapped_column(String(16))
    timesteps: Mapped[int] = mapped_column(BigInteger)
    seed: Mapped[int] = mapped_column(BigInteger)
    n_envs: Mapped[int] = mapped_column(Integer)
    config: Mapped[dict] = mapped_column(JSON)
    advice: Mapped[dict | None] = mapped_column(JSON, default=None)
    status: Mapped[str] = mapped_column(String(16), default="queued", index=True)
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
