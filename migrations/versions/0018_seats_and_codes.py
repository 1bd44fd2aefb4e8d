"""Freed seats and a code for every outcome (issue 45 §1-2).

- ``open_links.time_limit_min``: an open link's time per member (``NULL``: none);
  ``open_links.decline_code``: the code a visitor who declines, or a member who withdraws,
  is given; ``study_link_options.gate_code``: the code of a participant the gold gate stops.
- ``members.deadline_at``: when a member who joined through a timed link runs out of time;
  ``members.withdrawn_at``: when they withdrew (their labels are kept, and left out of
  everything); ``members.seat_freed_at``: when their seat on the link was given back, once;
  ``participants.gate_stopped_at``: when the gold gate stopped them mid-study.

Plain ``ADD COLUMN``s: every row is kept, and a member who joined before has no deadline.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-27
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0018"
down_revision: str | None = "0017"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_TIME_LIMIT = "time_limit_min IS NULL OR (time_limit_min >= 1 AND time_limit_min <= 10080)"
_MEMBER_TIMES = ("deadline_at", "withdrawn_at", "seat_freed_at")


def upgrade() -> None:
    with op.batch_alter_table("open_links") as batch:
        batch.add_column(sa.Column("time_limit_min", sa.Integer(), nullable=True))
        batch.add_column(sa.Column("decline_code", sa.String(100), nullable=True))
        batch.create_check_constraint("time_limit", _TIME_LIMIT)
    op.add_column("study_link_options", sa.Column("gate_code", sa.String(100), nullable=True))
    for column in _MEMBER_TIMES:
        op.add_column("members", sa.Column(column, sa.DateTime(timezone=True), nullable=True))
    op.add_column(
        "participants", sa.Column("gate_stopped_at", sa.DateTime(timezone=True), nullable=True)
    )


def downgrade() -> None:
    op.drop_column("participants", "gate_stopped_at")
    for column in reversed(_MEMBER_TIMES):
        op.drop_column("members", column)
    op.drop_column("study_link_options", "gate_code")
    with op.batch_alter_table("open_links") as batch:
        batch.drop_constraint("time_limit", type_="check")
        batch.drop_column("decline_code")
        batch.drop_column("time_limit_min")
