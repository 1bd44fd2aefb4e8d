"""Labels a researcher can trust (issue 28): gold items and their answers, a qualification
gate on gold accuracy, researcher exclusion of participants, "can't tell" answers and a
practice phase.

- ``gold_items``: a study's pairs with an objective answer; ``gold_answers``: each
  participant's copy of them, at a seeded position among the bracket's matches.
- ``studies.allow_ties`` (a participant may answer "can't tell") and
  ``studies.practice_pairs`` (0, or 2 to 5 practice pairs before the bracket).
- ``labels.tie``: the participant could not tell; the bracket advanced by a seeded coin.
- ``crowd_settings.gold_gate`` (the lowest acceptable upper bound of gold accuracy, NULL for
  no gate) and ``crowd_settings.gate_excludes`` (exclude a participant the gate flags).
- ``participants.excluded`` and ``participants.exclusion_reason``: left out of pooling and
  exports; their labels are kept.

Plain ``ADD COLUMN`` with server defaults and new tables: every existing row is kept.

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-25
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0014"
down_revision: str | None = "0013"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WHEN = sa.DateTime(timezone=True)


def _flag(name: str) -> sa.Column:
    return sa.Column(name, sa.Boolean(), nullable=False, server_default=sa.false())


def upgrade() -> None:
    op.add_column("studies", _flag("allow_ties"))
    op.add_column(
        "studies", sa.Column("practice_pairs", sa.Integer(), nullable=False, server_default="0")
    )
    op.add_column("labels", _flag("tie"))
    op.add_column("crowd_settings", sa.Column("gold_gate", sa.Float(), nullable=True))
    op.add_column("crowd_settings", _flag("gate_excludes"))
    op.add_column("participants", _flag("excluded"))
    op.add_column("participants", sa.Column("exclusion_reason", sa.String(200), nullable=True))
    op.create_table(
        "gold_items",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("study_id", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("a", sa.Integer(), nullable=False),
        sa.Column("b", sa.Integer(), nullable=False),
        sa.Column("answer", sa.Integer(), nullable=False),
        sa.Column("created_at", _WHEN, nullable=False),
        sa.ForeignKeyConstraint(
            ["study_id"],
            ["studies.id"],
            ondelete="CASCADE",
            name=op.f("fk_gold_items_study_id_studies"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_gold_items")),
    )
    op.create_index(op.f("ix_gold_items_study_id"), "gold_items", ["study_id"])
    op.create_table(
        "gold_answers",
        sa.Column("participant_id", sa.Integer(), nullable=False),
        sa.Column("gold_item_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("a_left", sa.Boolean(), nullable=False),
        sa.Column("winner", sa.Integer(), nullable=True),
        sa.Column("response_ms", sa.BigInteger(), nullable=True),
        sa.Column("answered_at", _WHEN, nullable=True),
        sa.ForeignKeyConstraint(
            ["participant_id"],
            ["participants.id"],
            ondelete="CASCADE",
            name=op.f("fk_gold_answers_participant_id_participants"),
        ),
        sa.ForeignKeyConstraint(
            ["gold_item_id"],
            ["gold_items.id"],
            ondelete="CASCADE",
            name=op.f("fk_gold_answers_gold_item_id_gold_items"),
        ),
        sa.PrimaryKeyConstraint("participant_id", "gold_item_id", name=op.f("pk_gold_answers")),
    )


def downgrade() -> None:
    op.drop_table("gold_answers")
    op.drop_index(op.f("ix_gold_items_study_id"), table_name="gold_items")
    op.drop_table("gold_items")
    for table, column in (
        ("participants", "exclusion_reason"),
        ("participants", "excluded"),
        ("crowd_settings", "gate_excludes"),
        ("crowd_settings", "gold_gate"),
        ("labels", "tie"),
        ("studies", "practice_pairs"),
        ("studies", "allow_ties"),
    ):
        op.drop_column(table, column)
