"""Finish the survey respondents that concurrent submissions left unfinished (issue 24 F2).

Until this revision ``submit`` decided "finished" from the screen plan it read before its
write transaction, so a respondent whose last screens arrived together could end with every
screen answered and ``finished_at`` NULL (no completion code), for ever. Such respondents are
finished now, at the time their last screen was answered. Rows are only updated, never
removed; the downgrade leaves them finished.

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
        """
        UPDATE survey_respondents
        SET finished_at = (
            SELECT max(s.answered_at) FROM survey_screens s
            WHERE s.respondent_id = survey_respondents.id
        )
        WHERE finished_at IS NULL
          AND EXISTS (SELECT 1 FROM survey_screens s WHERE s.respondent_id = survey_respondents.id)
          AND NOT EXISTS (
            SELECT 1 FROM survey_screens s
            WHERE s.respondent_id = survey_respondents.id AND s.answered_at IS NULL
          )
        """
    )


def downgrade() -> None:
    pass  # a repair of data: the finished respondents stay finished
