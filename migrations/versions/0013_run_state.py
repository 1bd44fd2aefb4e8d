"""Run state in the database (issue 26 §4): each metrics row and each saved checkpoint of a
run as a row (``run_metrics``, ``run_checkpoints``), written by the run's executor, so that
pages and the API never read a run folder. New tables only: every existing row is kept;
runs trained before this revision are imported from their folders by the worker's backfill
(:func:`app.runs.run_state.import_folder`).

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-25
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0013"
down_revision: str | None = "0012"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def _run_fk(table: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        ["run_id"], ["runs.id"], ondelete="CASCADE", name=op.f(f"fk_{table}_run_id_runs")
    )


def upgrade() -> None:
    op.create_table(
        "run_metrics",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("timesteps", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.Column("row", sa.JSON(), nullable=False),
        _run_fk("run_metrics"),
        sa.PrimaryKeyConstraint("run_id", "timesteps", name=op.f("pk_run_metrics")),
    )
    op.create_table(
        "run_checkpoints",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("step", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.Column("saved_at", sa.DateTime(timezone=True), nullable=False),
        _run_fk("run_checkpoints"),
        sa.PrimaryKeyConstraint("run_id", "step", name=op.f("pk_run_checkpoints")),
    )


def downgrade() -> None:
    op.drop_table("run_checkpoints")
    op.drop_table("run_metrics")
