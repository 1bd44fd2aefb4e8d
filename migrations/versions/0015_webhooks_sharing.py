"""Running a crowd study unattended (issue 29): webhooks with a transactional outbox, and
participants' consent to share their labels in a public dataset.

- ``webhooks``: a URL registered for a study or a survey, with the secret its deliveries are
  signed with (Standard Webhooks).
- ``webhook_events``: the outbox. An event is written in the same transaction as the change
  it reports, one row per webhook, and delivered at least once (``delivered_at``); its
  ``event_id`` is what receivers deduplicate by.
- ``webhook_attempts``: every delivery attempt, with its status or error.
- ``participants.share_consent`` and ``survey_respondents.share_consent``: agreed to have their
  labels shared in a dataset, under a salted hash of their id (false for everyone so far).

New tables and plain ``ADD COLUMN`` with a server default: every existing row is kept.

Revision ID: 0015
Revises: 0014
Create Date: 2026-11-25
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0015"
down_revision: str | None = "0014"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WHEN = sa.DateTime(timezone=True)


def _fk(table: str, column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column], [f"{target}.id"], ondelete="CASCADE", name=op.f(f"fk_{table}_{column}_{target}")
    )


def upgrade() -> None:
    for table in ("participants", "survey_respondents"):
        op.add_column(
            table,
            sa.Column("share_consent", sa.Boolean(), nullable=False, server_default=sa.false()),
        )
    op.create_table(
        "webhooks",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=True),
        sa.Column("survey_id", sa.Integer(), nullable=True),
        sa.Column("url", sa.String(2000), nullable=False),
        sa.Column("secret", sa.String(100), nullable=False),
        sa.Column("created_at", _WHEN, nullable=False),
        _fk("webhooks", "study_id", "studies"),
        _fk("webhooks", "survey_id", "surveys"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_webhooks")),
    )
    op.create_index(op.f("ix_webhooks_study_id"), "webhooks", ["study_id"])
    op.create_index(op.f("ix_webhooks_survey_id"), "webhooks", ["survey_id"])
    op.create_table(
        "webhook_events",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("webhook_id", sa.Integer(), nullable=False),
        sa.Column("event_id", sa.String(64), nullable=False),
        sa.Column("type", sa.String(64), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False, server_default="0"),
        sa.Column("next_attempt_at", _WHEN, nullable=False),
        sa.Column("delivered_at", _WHEN, nullable=True),
        _fk("webhook_events", "webhook_id", "webhooks"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_webhook_events")),
        sa.UniqueConstraint("event_id", name=op.f("uq_webhook_events_event_id")),
    )
    op.create_index(
        op.f("ix_webhook_events_due"), "webhook_events", ["delivered_at", "next_attempt_at"]
    )
    op.create_table(
        "webhook_attempts",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("event_id", sa.Integer(), nullable=False),
        sa.Column("attempted_at", _WHEN, nullable=False),
        sa.Column("status_code", sa.Integer(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("duration_ms", sa.Integer(), nullable=False),
        _fk("webhook_attempts", "event_id", "webhook_events"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_webhook_attempts")),
    )
    op.create_index(op.f("ix_webhook_attempts_event_id"), "webhook_attempts", ["event_id"])


def downgrade() -> None:
    op.drop_index(op.f("ix_webhook_attempts_event_id"), table_name="webhook_attempts")
    op.drop_table("webhook_attempts")
    op.drop_index(op.f("ix_webhook_events_due"), table_name="webhook_events")
    op.drop_table("webhook_events")
    op.drop_index(op.f("ix_webhooks_survey_id"), table_name="webhooks")
    op.drop_index(op.f("ix_webhooks_study_id"), table_name="webhooks")
    op.drop_table("webhooks")
    for table in ("survey_respondents", "participants"):
        op.drop_column(table, "share_consent")
