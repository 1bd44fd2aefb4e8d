"""Checkpoint artefacts: what the executor computed at each checkpoint of a run (the agent's
trees for every judge, their conformance to the run's advice and the per-candidate table), so
that the web tier only reads them.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "checkpoint_artefacts",
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("step", sa.BigInteger(), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["run_id"],
            ["runs.id"],
            ondelete="CASCADE",
            name=op.f("fk_checkpoint_artefacts_run_id_runs"),
        ),
        sa.PrimaryKeyConstraint("run_id", "step", name=op.f("pk_checkpoint_artefacts")),
    )


def downgrade() -> None:
    op.drop_table("checkpoint_artefacts")
