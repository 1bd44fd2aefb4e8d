"""Whether a study participant came through the study's open link (issue 24, F5): only they
get its completion code and redirect, as survey respondents already do.

Participants who exist already in a study with an open link are marked as having come
through it: the table cannot tell an invited one from a crowd worker who joined without
external ids, and hiding the code from a crowd worker part way through would stop them
being paid; new invited participants never get it. Plain ``ADD COLUMN`` (no table copy,
whose drop would cascade to matches and labels): every row is kept.

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-24
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0011"
down_revision: str | None = "0010"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.add_column(
        "participants",
        sa.Column("via_link", sa.Boolean(), nullable=False, server_default=sa.false()),
    )
    op.execute(
        sa.text(
            "UPDATE participants SET via_link = :yes WHERE EXISTS (SELECT 1 FROM crowd_settings c"
            " WHERE c.study_id = participants.study_id)"
        ).bindparams(yes=True)
    )


def downgrade() -> None:
    op.drop_column("participants", "via_link")
