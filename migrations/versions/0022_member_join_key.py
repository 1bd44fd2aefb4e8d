"""The consent form's one-time key (``members.join_key``), unique per collection: a second
post of the same form (a double click on "I agree", before the first answer set the cookie)
resumes the member the first one made instead of taking a second seat.

A plain ``ADD COLUMN`` (``NULL`` for every earlier member, and NULLs never collide in a
unique index) and the index beside the external id's.

Revision ID: 0022
Revises: 0021
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0022"
down_revision: str | None = "0021"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INDEX = "uq_members_collection_join_key"


def upgrade() -> None:
    op.add_column("members", sa.Column("join_key", sa.String(32), nullable=True))
    op.create_index(
        _INDEX, "members", ["collection_kind", "collection_id", "join_key"], unique=True
    )


def downgrade() -> None:
    op.drop_index(_INDEX, table_name="members")
    with op.batch_alter_table("members") as batch:
        batch.drop_column("join_key")
