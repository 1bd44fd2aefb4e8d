"""Invite tokens are looked up by their SHA-256 (``participants.token_hash``), then compared
in constant time.

Plain ``ADD COLUMN`` and ``CREATE INDEX`` (no table copy): SQLite's batch mode would drop and
re-create ``participants``, and with foreign keys on that cascades to every match and label.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-22
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_participants = sa.table(
    "participants",
    sa.column("id", sa.Integer()),
    sa.column("token", sa.String()),
    sa.column("token_hash", sa.String()),
)


def upgrade() -> None:
    # NOT NULL needs a default for the existing rows; each gets its real hash just below.
    op.add_column(
        "participants",
        sa.Column("token_hash", sa.String(length=64), nullable=False, server_default=""),
    )
    bind = op.get_bind()
    rows = bind.execute(sa.select(_participants.c.id, _participants.c.token)).all()
    for pid, token in rows:
        bind.execute(
            _participants.update()
            .where(_participants.c.id == pid)
            .values(token_hash=hashlib.sha256(token.encode()).hexdigest())
        )
    if bind.dialect.name != "sqlite":  # SQLite cannot drop a default in place; it is unused
        op.alter_column("participants", "token_hash", server_default=None)
    op.create_index(op.f("ix_participants_token_hash"), "participants", ["token_hash"], unique=True)


def downgrade() -> None:
    op.drop_index(op.f("ix_participants_token_hash"), table_name="participants")
    op.drop_column("participants", "token_hash")
