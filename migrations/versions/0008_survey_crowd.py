"""Crowd-ready surveys: a survey's open link ``/q/<slug>`` with its options, and on each
respondent whether they came through it and their external ids (UNIQUE per survey).

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0008"
down_revision: str | None = "0007"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "survey_crowd_settings",
        sa.Column("survey_id", sa.Integer(), nullable=False),
        sa.Column("slug", sa.String(64), nullable=False),
        sa.Column("enabled", sa.Boolean(), nullable=False),
        sa.Column("max_participants", sa.Integer(), nullable=False),
        sa.Column("joined", sa.Integer(), nullable=False),
        sa.Column("declines", sa.Integer(), nullable=False),
        sa.Column("external_params", sa.JSON(), nullable=False),
        sa.Column("consent_text", sa.Text(), nullable=True),
        sa.Column("completion_code", sa.String(100), nullable=True),
        sa.Column("redirect_url", sa.String(500), nullable=True),
        sa.CheckConstraint(
            "max_participants >= 1 AND joined >= 0 AND joined <= max_participants "
            "AND declines >= 0",
            name=op.f("ck_survey_crowd_settings_counts"),
        ),
        sa.ForeignKeyConstraint(
            ["survey_id"],
            ["surveys.id"],
            ondelete="CASCADE",
            name=op.f("fk_survey_crowd_settings_survey_id_surveys"),
        ),
        sa.PrimaryKeyConstraint("survey_id", name=op.f("pk_survey_crowd_settings")),
        sa.UniqueConstraint("slug", name=op.f("uq_survey_crowd_settings_slug")),
    )
    # Plain ADD COLUMN and CREATE INDEX (no table copy): SQLite's batch mode would drop and
    # recreate survey_respondents, and the drop would cascade to every screen and answer.
    op.add_column(
        "survey_respondents",
        sa.Column("via_link", sa.Boolean(), nullable=False, server_default=sa.false()),
    )
    op.add_column("survey_respondents", sa.Column("external_id", sa.String(200), nullable=True))
    op.add_column("survey_respondents", sa.Column("external_ids", sa.JSON(), nullable=True))
    op.create_index(
        op.f("uq_survey_respondents_survey_external_id"),
        "survey_respondents",
        ["survey_id", "external_id"],
        unique=True,
    )


def downgrade() -> None:
    op.drop_index(op.f("uq_survey_respondents_survey_external_id"), table_name="survey_respondents")
    op.drop_column("survey_respondents", "external_ids")
    op.drop_column("survey_respondents", "external_id")
    op.drop_column("survey_respondents", "via_link")
    op.drop_table("survey_crowd_settings")
