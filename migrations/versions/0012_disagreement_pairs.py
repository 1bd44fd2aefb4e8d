"""Disagreement pairs (issue 25 §5): a study may ask each participant extra pairs after the
bracket, where their advice and a no-advice baseline disagree. ``studies.disagreement_pairs``
says how many (0 for every existing study), ``candidates.baseline_return`` holds the
baseline's return from each candidate (NULL for existing ones), and ``disagreement_pairs``
holds the pairs and their answers. Plain ``ADD COLUMN`` (no table copy, whose drop would
cascade to candidates, participants and labels): every row is kept.

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-25
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0012"
down_revision: str | None = "0011"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WHEN = sa.DateTime(timezone=True)


def upgrade() -> None:
    op.add_column(
        "studies",
        sa.Column("disagreement_pairs", sa.Integer(), nullable=False, server_default="0"),
    )
    op.add_column("candidates", sa.Column("baseline_return", sa.Float(), nullable=True))
    op.create_table(
        "disagreement_pairs",
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("a", sa.Integer(), nullable=False),
        sa.Column("b", sa.Integer(), nullable=False),
        sa.Column("a_left", sa.Boolean(), nullable=False),
        sa.Column("winner", sa.Integer(), nullable=True),
        sa.Column("response_ms", sa.BigInteger(), nullable=True),
        sa.Column("shown_at", _WHEN, nullable=False),
        sa.Column("answered_at", _WHEN, nullable=True),
        sa.ForeignKeyConstraint(
            ["participant_id"],
            ["participants.id"],
            ondelete="CASCADE",
            name=op.f("fk_disagreement_pairs_participant_id_participants"),
        ),
        sa.PrimaryKeyConstraint("participant_id", "position", name=op.f("pk_disagreement_pairs")),
    )


def downgrade() -> None:
    op.drop_table("disagreement_pairs")
    op.drop_column("candidates", "baseline_return")
    op.drop_column("studies", "disagreement_pairs")
