"""Tree-reading surveys (the paper's user study): surveys, their stimuli (two frozen trees
each), respondents with invite tokens, each respondent's screens, and their answers.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-23
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WHEN = sa.DateTime(timezone=True)


def _fk(table: str, column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column], [f"{target}.id"], ondelete="CASCADE", name=op.f(f"fk_{table}_{column}_{target}")
    )


def upgrade() -> None:
    op.create_table(
        "surveys",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("intro", sa.Text(), nullable=False),
        sa.Column("template", sa.String(16), nullable=False),
        sa.Column("questions", sa.JSON(), nullable=False),
        sa.Column("highlights", sa.Boolean(), nullable=False),
        sa.Column("assignment", sa.String(16), nullable=False),
        sa.Column("exclusion_rule", sa.String(32), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("rr_counter", sa.Integer(), nullable=False),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.CheckConstraint(
            "assignment IN ('all', 'round_robin')", name=op.f("ck_surveys_assignment")
        ),
        sa.CheckConstraint(
            "exclusion_rule IN ('none', 'attention_check')", name=op.f("ck_surveys_exclusion_rule")
        ),
        sa.CheckConstraint("rr_counter >= 0", name=op.f("ck_surveys_rr_counter")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_surveys")),
    )
    op.create_table(
        "survey_stimuli",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("survey_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("label", sa.String(200), nullable=False),
        sa.Column("attention_check", sa.Boolean(), nullable=False),
        sa.Column("check_question", sa.String(32), nullable=True),
        sa.Column("trees", sa.JSON(), nullable=False),
        sa.Column("expected", sa.JSON(), nullable=False),
        _fk("survey_stimuli", "survey_id", "surveys"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_survey_stimuli")),
        sa.UniqueConstraint(
            "survey_id", "position", name=op.f("uq_survey_stimuli_survey_id_position")
        ),
    )
    op.create_table(
        "survey_respondents",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("survey_id", sa.Integer(), nullable=False),
        sa.Column("token", sa.String(64), nullable=False),
        sa.Column("token_hash", sa.String(64), nullable=False),
        sa.Column("name", sa.String(200), nullable=True),
        sa.Column("stimulus_id", sa.Integer(), nullable=True),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.Column("started_at", _WHEN, nullable=True),
        sa.Column("finished_at", _WHEN, nullable=True),
        _fk("survey_respondents", "survey_id", "surveys"),
        _fk("survey_respondents", "stimulus_id", "survey_stimuli"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_survey_respondents")),
        sa.UniqueConstraint("token", name=op.f("uq_survey_respondents_token")),
    )
    op.create_index(op.f("ix_survey_respondents_survey_id"), "survey_respondents", ["survey_id"])
    op.create_index(
        op.f("ix_survey_respondents_token_hash"), "survey_respondents", ["token_hash"], unique=True
    )
    op.create_table(
        "survey_screens",
        sa.Column("respondent_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("stimulus_id", sa.Integer(), nullable=False),
        sa.Column("tree1_left", sa.Boolean(), nullable=False),
        sa.Column("shown_at", _WHEN, nullable=True),
        sa.Column("answered_at", _WHEN, nullable=True),
        sa.Column("screen_ms", sa.BigInteger(), nullable=True),
        sa.CheckConstraint("screen_ms >= 0", name=op.f("ck_survey_screens_screen_ms")),
        _fk("survey_screens", "respondent_id", "survey_respondents"),
        _fk("survey_screens", "stimulus_id", "survey_stimuli"),
        sa.PrimaryKeyConstraint("respondent_id", "position", name=op.f("pk_survey_screens")),
        sa.UniqueConstraint(
            "respondent_id", "stimulus_id", name=op.f("uq_survey_screens_respondent_id_stimulus_id")
        ),
    )
    op.create_table(
        "survey_answers",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("respondent_id", sa.Integer(), nullable=False),
        sa.Column("stimulus_id", sa.Integer(), nullable=False),
        sa.Column("question", sa.String(32), nullable=False),
        sa.Column("value", sa.Text(), nullable=False),
        sa.Column("confidence", sa.Integer(), nullable=True),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.CheckConstraint(
            "confidence IS NULL OR (confidence >= 1 AND confidence <= 5)",
            name=op.f("ck_survey_answers_confidence"),
        ),
        _fk("survey_answers", "respondent_id", "survey_respondents"),
        _fk("survey_answers", "stimulus_id", "survey_stimuli"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_survey_answers")),
        sa.UniqueConstraint(
            "respondent_id",
            "stimulus_id",
            "question",
            name=op.f("uq_survey_answers_respondent_id_stimulus_id_question"),
        ),
    )
    op.create_index(op.f("ix_survey_answers_respondent_id"), "survey_answers", ["respondent_id"])


def downgrade() -> None:
    for table in (
        "survey_answers",
        "survey_screens",
        "survey_respondents",
        "survey_stimuli",
        "surveys",
    ):
        op.drop_table(table)
