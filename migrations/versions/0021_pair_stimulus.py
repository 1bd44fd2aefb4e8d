"""What the pairs after the bracket showed (issue 41 §3): ``disagreement_pairs.stimulus`` and
``consistency_checks.stimulus``, ``still`` or ``clip``, as ``labels.stimulus`` is for the
bracket's matches; every earlier answer was given on two stills.

Plain ``ADD COLUMN``s: every row is kept.

Revision ID: 0021
Revises: 0020
Create Date: 2026-11-28
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0021"
down_revision: str | None = "0020"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_TABLES = ("disagreement_pairs", "consistency_checks")


def upgrade() -> None:
    for table in _TABLES:
        op.add_column(
            table, sa.Column("stimulus", sa.String(8), nullable=False, server_default="still")
        )


def downgrade() -> None:
    for table in reversed(_TABLES):
        with op.batch_alter_table(table) as batch:
            batch.drop_column("stimulus")
