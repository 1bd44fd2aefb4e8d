"""Limits and reuse that hold under concurrency (issue 45 §4), enforced by the database.

- ``studies.webhook_count``, ``studies.gold_item_count`` and ``surveys.webhook_count``: how
  many webhooks and gold items each owner has, moved by ``UPDATE ... WHERE n < N`` in the
  transactions that add and remove them; backfilled from the rows that exist (an owner that
  has more than today's limit keeps them all, and adds none until below it).
- ``runs.config_digest`` and the partial unique index ``ix_runs_shared`` on ``(study_id,
  config_digest, seed) WHERE config_digest IS NOT NULL``: the run experiments share as their
  baseline or pilot at a study, config and seed. Backfilled on the run an experiment would
  have reused until now: the oldest ``ppo`` run that names advice and is neither failed nor
  cancelled, per study, config and seed.
- ``login_failures``: failed researcher logins, shared by every server process and host.

Plain ``ADD COLUMN``, ``CREATE INDEX`` and a new table (no table copy, whose drop would
cascade): every existing row is kept.

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-28
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0016"
down_revision: str | None = "0015"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_SHARED = sa.text("config_digest IS NOT NULL")
_runs = sa.table(
    "runs",
    sa.column("id", sa.Integer()),
    sa.column("study_id", sa.Integer()),
    sa.column("algo", sa.String()),
    sa.column("seed", sa.BigInteger()),
    sa.column("status", sa.String()),
    sa.column("config", sa.JSON()),
    sa.column("advice", sa.JSON()),
    sa.column("config_digest", sa.String()),
)
#: Each counter, and the rows it counts: (owner table, counter, counted table, owner column).
_COUNTERS = (
    ("studies", "webhook_count", "webhooks", "study_id"),
    ("studies", "gold_item_count", "gold_items", "study_id"),
    ("surveys", "webhook_count", "webhooks", "survey_id"),
)


def _digest(config: dict) -> str:
    """``app.runs.shared.config_digest`` as of this revision."""
    canonical = json.dumps(config, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def upgrade() -> None:
    for owner, counter, counted, column in _COUNTERS:
        op.add_column(owner, sa.Column(counter, sa.Integer(), nullable=False, server_default="0"))
        op.execute(
            f"UPDATE {owner} SET {counter} = (SELECT count(*) FROM {counted} "
            f"WHERE {counted}.{column} = {owner}.id)"
        )
    op.add_column("runs", sa.Column("config_digest", sa.String(64), nullable=True))
    _backfill_shared_runs()
    op.create_index(
        "ix_runs_shared",
        "runs",
        ["study_id", "config_digest", "seed"],
        unique=True,
        sqlite_where=_SHARED,
        postgresql_where=_SHARED,
    )
    op.create_table(
        "login_failures",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("address", sa.String(200), nullable=False),
        sa.Column("at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_login_failures")),
    )
    op.create_index("ix_login_failures_address", "login_failures", ["address", "at"])
    op.create_index(op.f("ix_login_failures_at"), "login_failures", ["at"])


def _backfill_shared_runs() -> None:
    """The digest on the oldest reusable run per study, config and seed (the one
    ``app.runs.experiments`` picked until now). Whether a run names advice is read in Python:
    the JSON column stores a run without advice as JSON null, not NULL."""
    bind = op.get_bind()
    rows = bind.execute(
        sa.select(_runs.c.id, _runs.c.study_id, _runs.c.seed, _runs.c.config, _runs.c.advice)
        .where(_runs.c.algo == "ppo", _runs.c.status.not_in(["failed", "cancelled"]))
        .order_by(_runs.c.id)
    ).all()
    seen: set[tuple[int, str, int]] = set()
    for run_id, study_id, seed, config, advice in rows:
        key = (study_id, _digest(config), seed)
        if advice is None or key in seen:
            continue
        seen.add(key)
        bind.execute(_runs.update().where(_runs.c.id == run_id).values(config_digest=key[1]))


def downgrade() -> None:
    op.drop_index(op.f("ix_login_failures_at"), table_name="login_failures")
    op.drop_index("ix_login_failures_address", table_name="login_failures")
    op.drop_table("login_failures")
    op.drop_index(
        "ix_runs_shared", table_name="runs", sqlite_where=_SHARED, postgresql_where=_SHARED
    )
    op.drop_column("runs", "config_digest")
    for owner, counter, _, _ in reversed(_COUNTERS):
        op.drop_column(owner, counter)
