"""Initial schema: studies, candidates, first-round bracket, participants, matches, labels.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def _created_at() -> sa.Column:
    return sa.Column("created_at", sa.DateTime(timezone=True), nullable=False)


def upgrade() -> None:
    op.create_table(
        "studies",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("env_id", sa.String(length=100), nullable=False),
        sa.Column("n_candidates", sa.Integer(), nullable=False),
        sa.Column("p", sa.Float(), nullable=False),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("sampling", sa.String(length=16), nullable=False),
        sa.Column("instructions", sa.Text(), nullable=False),
        sa.Column("status", sa.String(length=16), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        _created_at(),
        sa.CheckConstraint(
            "status IN ('preparing', 'ready', 'failed')", name=op.f("ck_studies_status")
        ),
        sa.CheckConstraint(
            "n_candidates >= 2 AND n_candidates <= 128", name=op.f("ck_studies_n_candidates")
        ),
        sa.CheckConstraint("p >= 0 AND p <= 1", name=op.f("ck_studies_p")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_studies")),
    )
    op.create_table(
        "candidates",
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("id", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("qpos", sa.JSON(), nullable=False),
        sa.Column("qvel", sa.JSON(), nullable=False),
        sa.Column("env_reward", sa.Float(), nullable=False),
        sa.Column("image_path", sa.String(length=255), nullable=False),
        sa.Column("thumb_path", sa.String(length=255), nullable=False),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            ondelete="CASCADE",
            name=op.f("fk_candidates_study_id_studies"),
        ),
        sa.PrimaryKeyConstraint("study_id", "id", name=op.f("pk_candidates")),
    )
    op.create_table(
        "participants",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("token", sa.String(length=64), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=True),
        _created_at(),
        sa.Column("last_active_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            ondelete="CASCADE",
            name=op.f("fk_participants_study_id_studies"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_participants")),
        sa.UniqueConstraint("token", name=op.f("uq_participants_token")),
    )
    op.create_index(op.f("ix_participants_study_id"), "participants", ["study_id"])
    op.create_table(
        "bracket_slots",
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("slot", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("a", sa.Integer(), nullable=False),
        sa.Column("b", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(
            ["study_id", "a"],
            ["candidates.study_id", "candidates.id"],
            ondelete="CASCADE",
            name=op.f("fk_bracket_slots_study_id_a_candidates"),
        ),
        sa.ForeignKeyConstraint(
            ["study_id", "b"],
            ["candidates.study_id", "candidates.id"],
            ondelete="CASCADE",
            name=op.f("fk_bracket_slots_study_id_b_candidates"),
        ),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            ondelete="CASCADE",
            name=op.f("fk_bracket_slots_study_id_studies"),
        ),
        sa.PrimaryKeyConstraint("study_id", "slot", name=op.f("pk_bracket_slots")),
    )
    op.create_table(
        "matches",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("round", sa.Integer(), nullable=False),
        sa.Column("slot", sa.Integer(), nullable=False),
        sa.Column("a", sa.Integer(), nullable=False),
        sa.Column("b", sa.Integer(), nullable=False),
        _created_at(),
        sa.CheckConstraint("a <> b", name=op.f("ck_matches_distinct_players")),
        sa.ForeignKeyConstraint(
            ["participant_id"],
            ["participants.id"],
            ondelete="CASCADE",
            name=op.f("fk_matches_participant_id_participants"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_matches")),
        sa.UniqueConstraint(
            "participant_id", "round", "slot", name=op.f("uq_matches_participant_id_round_slot")
        ),
    )
    op.create_table(
        "labels",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("match_id", sa.Integer(), nullable=False),
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("winner", sa.Integer(), nullable=False),
        _created_at(),
        sa.Column("response_ms", sa.BigInteger(), nullable=True),
        sa.CheckConstraint("response_ms >= 0", name=op.f("ck_labels_response_ms")),
        sa.ForeignKeyConstraint(
            ["match_id"],
            ["matches.id"],
            ondelete="CASCADE",
            name=op.f("fk_labels_match_id_matches"),
        ),
        sa.ForeignKeyConstraint(
            ["participant_id"],
            ["participants.id"],
            ondelete="CASCADE",
            name=op.f("fk_labels_participant_id_participants"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_labels")),
        # At most one label per match, enforced by the database.
        sa.UniqueConstraint("match_id", name=op.f("uq_labels_match_id")),
    )
    op.create_index(op.f("ix_labels_participant_id"), "labels", ["participant_id"])


def downgrade() -> None:
    op.drop_index(op.f("ix_labels_participant_id"), table_name="labels")
    op.drop_table("labels")
    op.drop_table("matches")
    op.drop_table("bracket_slots")
    op.drop_index(op.f("ix_participants_study_id"), table_name="participants")
    op.drop_table("participants")
    op.drop_table("candidates")
    op.drop_table("studies")
