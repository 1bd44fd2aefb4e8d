"""What every table shares: the declarative base with its constraint names, the status
enums stored in columns, and time helpers."""

from __future__ import annotations

from datetime import UTC, datetime
from enum import StrEnum

from sqlalchemy import (
    CheckConstraint,
    Enum,
    MetaData,
)
from sqlalchemy.orm import DeclarativeBase


class StudyStatus(StrEnum):
    """Where a study stands: its candidates are being prepared, ready, or failed."""

    PREPARING = "preparing"
    READY = "ready"
    FAILED = "failed"


class RunStatus(StrEnum):
    """Where a training run stands (``queued`` -> ``running`` -> one of the last four)."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"


class ExperimentRole(StrEnum):
    """A run's part in an experiment: trained with the advice, or a no-advice baseline that
    the verdict compares with (``baseline``) or that picks the contested matches (``pilot``)."""

    ADVISED = "advised"
    BASELINE = "baseline"
    PILOT = "pilot"


STUDY_STATUSES: tuple[str, ...] = tuple(s.value for s in StudyStatus)
RUN_STATUSES: tuple[str, ...] = tuple(s.value for s in RunStatus)


def enum_type(members: type[StrEnum], length: int = 16) -> Enum:
    """A ``VARCHAR(length)`` column of ``members``' values, read back as members.

    Not a database enum type (``native_enum=False``) and no constraint of its own, so the
    schema stays the migrations' (``status`` and ``role`` have CHECK constraints). A value
    that is no member is refused when written (``validate_strings``): loading one would fail.
    """
    return Enum(
        members,
        native_enum=False,
        create_constraint=False,
        validate_strings=True,
        length=length,
        values_callable=lambda enum: [member.value for member in enum],
    )


def status_check(statuses: type[StrEnum]) -> CheckConstraint:
    """``status IN (...)`` over every member of ``statuses``."""
    listed = ", ".join(f"'{s.value}'" for s in statuses)
    return CheckConstraint(f"status IN ({listed})", name="status")


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
