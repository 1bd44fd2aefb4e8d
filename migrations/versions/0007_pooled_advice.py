"""Pooled advice: a run may train on several finished participants' trees at once.

``runs.advice_pool`` lists ``{"participant_id", "tree"}`` per pooled participant (NULL for a
run on one participant's, a teacher's or no advice); such a run's ``advice`` is the pooled
verdict tree and its ``participant_id`` and ``teacher`` are NULL.

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0007"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("advice_pool", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("advice_pool")
