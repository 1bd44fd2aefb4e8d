"""Crowd-ready studies: a study's open link and quality settings, participants' external ids
(UNIQUE per study), which side each match shows on the left and which side was chosen, and
the after-bracket consistency check.

Revision ID: 0006
Revises: 0005
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0006"
down_revision: str | None = "0005"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WHEN = sa.DateTime(timezone=True)


def _fk(table: str, column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column], [f"{target}.id"], ondelete="CASCADE", name=op.f(f"fk_{table}_{column}_{target}")
    )


def upgrade() -> None:
    op.create_table(
        "crowd_settings",
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("slug", sa.String(64), nullable=False),
        sa.Column("enabled", sa.Boolean(), nullable=False),
        sa.Column("max_participants", sa.Integer(), nullable=False),
        sa.Column("joined", sa.Integer(), nullable=False),
        sa.Column("declines", sa.Integer(), nullable=False),
        sa.Column("external_params", sa.JSON(), nullable=False),
        sa.Column("consent_text", sa.Text(), nullable=True),
        sa.Column("completion_code", sa.String(100), nullable=True),
        sa.Column("redirect_url", sa.String(500), nullable=True),
        sa.Column("consistency_check", sa.Boolean(), nullable=False),
        sa.Column("speed_threshold_ms", sa.Integer(), nullable=False),
        sa.CheckConstraint(
            "max_participants >= 1 AND joined >= 0 AND joined <= "
            "max_participants AND declines >= 0",
            name=op.f("ck_crowd_settings_counts"),
        ),
        sa.CheckConstraint("speed_threshold_ms >= 0", name=op.f("ck_crowd_settings_speed")),
        _fk("crowd_settings", "study_id", "studies"),
        sa.PrimaryKeyConstraint("study_id", name=op.f("pk_crowd_settings")),
        sa.UniqueConstraint("slug", name=op.f("uq_crowd_settings_slug")),
    )
    # Plain ADD COLUMN and CREATE INDEX (no table copy): SQLite's batch mode would drop and
    # recreate these tables, and the drop would cascade to every match and label.
    op.add_column("participants", sa.Column("external_id", sa.String(200), nullable=True))
    op.add_column("participants", sa.Column("external_ids", sa.JSON(), nullable=True))
    op.create_index(
        op.f("uq_participants_study_external_id"),
        "participants",
        ["study_id", "external_id"],
        unique=True,
    )
    op.add_column(
        "matches", sa.Column("a_left", sa.Boolean(), nullable=False, server_default=sa.true())
    )
    op.add_column("labels", sa.Column("chose_left", sa.Boolean(), nullable=True))
    op.create_table(
        "consistency_checks",
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("match_id", sa.Integer(), nullable=False),
        sa.Column("a_left", sa.Boolean(), nullable=False),
        sa.Column("winner", sa.Integer(), nullable=True),
        sa.Column("response_ms", sa.BigInteger(), nullable=True),
        sa.Column("shown_at", _WHEN, nullable=False),
        sa.Column("answered_at", _WHEN, nullable=True),
        _fk("consistency_checks", "participant_id", "participants"),
        _fk("consistency_checks", "match_id", "matches"),
        sa.PrimaryKeyConstraint("participant_id", name=op.f("pk_consistency_checks")),
    )


def downgrade() -> None:
    op.drop_table("consistency_checks")
    op.drop_column("labels", "chose_left")
    op.drop_column("matches", "a_left")
    op.drop_index(op.f("uq_participants_study_external_id"), table_name="participants")
    op.drop_column("participants", "external_ids")
    op.drop_column("participants", "external_id")
    op.drop_table("crowd_settings")
