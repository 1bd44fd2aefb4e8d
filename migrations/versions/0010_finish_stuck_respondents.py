"""Mark finished the survey respondents left unfinished by two screens submitted at once
(issue 24, F2): every screen answered, ``finished_at`` empty. Their ``finished_at`` becomes
the time of their last answered screen. An ``UPDATE`` only: every row is kept.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-24
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0010"
down_revision: str | None = "0009"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.execute(
        "UPDATE survey_respondents SET finished_at = ("
        " SELECT MAX(s.answered_at) FROM survey_screens s"
        " WHERE s.respondent_id = survey_respondents.id)"
        " WHERE finished_at IS NULL"
        " AND EXISTS (SELECT 1 FROM survey_screens s"
        " WHERE s.respondent_id = survey_respondents.id)"
        " AND NOT EXISTS (SELECT 1 FROM survey_screens s"
        " WHERE s.respondent_id = survey_respondents.id AND s.answered_at IS NULL)"
    )


def downgrade() -> None:
    """Nothing to undo: the repaired respondents did answer every screen."""
