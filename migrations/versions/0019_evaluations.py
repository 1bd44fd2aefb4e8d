"""Agent evaluations (issue 41): a third kind of collection, whose members are evaluators.

- ``evaluations``: two groups of runs of one env, the question, the evaluator kind and the
  design; ``evaluation_runs`` their slots and arms; ``evaluation_stimuli`` what each slot's
  agent does, rendered; ``evaluators`` (members of kind ``evaluation``) and their
  ``evaluation_pairs``, each answered once.
- ``members.collection_kind`` and ``open_links.collection_kind`` also take ``evaluation``.

Only new tables and a wider CHECK: every row is kept.

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-27
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0019"
down_revision: str | None = "0018"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_KIND_TABLES = ("members", "open_links")
_KINDS_BEFORE = "collection_kind IN ('study', 'survey')"
_KINDS_AFTER = "collection_kind IN ('study', 'survey', 'evaluation')"
_STATUS = "status IN ('preparing', 'ready', 'failed')"


#: Revision 0017 named the kind checks ``ck_<table>_ck_<table>_collection_kind`` (its
#: explicit name went through the naming convention too); this one names them as the models
#: do. Both are names *before* the convention is applied.
_OLD_NAME = "ck_{table}_collection_kind"
_NEW_NAME = "collection_kind"


def _kinds(check: str, *, drop: str, create: str) -> None:
    for table in _KIND_TABLES:
        with op.batch_alter_table(table) as batch:
            batch.drop_constraint(drop.format(table=table), type_="check")
            batch.create_check_constraint(create.format(table=table), check)


def upgrade() -> None:
    _kinds(_KINDS_AFTER, drop=_OLD_NAME, create=_NEW_NAME)
    _create_evaluations()
    _create_evaluation_runs()
    _create_evaluators()
    _create_pairs()


def _create_evaluations() -> None:
    op.create_table(
        "evaluations",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("env_id", sa.String(100), nullable=False),
        sa.Column("experiment_id", sa.Integer(), nullable=True),
        sa.Column("evaluator_kind", sa.String(16), nullable=False),
        sa.Column("question", sa.Text(), nullable=False),
        sa.Column("instructions", sa.Text(), nullable=False),
        sa.Column("advisor_id", sa.Integer(), nullable=True),
        sa.Column("show_bracket", sa.Boolean(), nullable=False),
        sa.Column("stimulus", sa.String(8), nullable=False),
        sa.Column("pairs_per_evaluator", sa.Integer(), nullable=False),
        sa.Column("target_win_rate", sa.Float(), nullable=False),
        sa.Column("needed_evaluators", sa.Integer(), nullable=True),
        sa.Column("design_power", sa.Float(), nullable=True),
        sa.Column("seed", sa.BigInteger(), nullable=False),
        sa.Column("evaluator_counter", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("clips_ready", sa.Boolean(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["experiment_id"],
            ["experiments.id"],
            name="fk_evaluations_experiment_id_experiments",
            ondelete="SET NULL",
        ),
        sa.ForeignKeyConstraint(
            ["advisor_id"],
            ["participants.id"],
            name="fk_evaluations_advisor_id_participants",
            ondelete="SET NULL",
        ),
        sa.CheckConstraint(_STATUS, name="ck_evaluations_status"),
        sa.CheckConstraint(
            "evaluator_kind IN ('advisor', 'others')", name="ck_evaluations_evaluator_kind"
        ),
        sa.CheckConstraint("stimulus IN ('still', 'clip')", name="ck_evaluations_stimulus"),
        sa.CheckConstraint(
            "pairs_per_evaluator >= 1 AND pairs_per_evaluator <= 200", name="ck_evaluations_pairs"
        ),
        sa.CheckConstraint(
            "target_win_rate > 0.5 AND target_win_rate < 1", name="ck_evaluations_target"
        ),
        sa.CheckConstraint("evaluator_counter >= 0", name="ck_evaluations_evaluator_counter"),
        sa.PrimaryKeyConstraint("id", name="pk_evaluations"),
    )


def _create_evaluation_runs() -> None:
    op.create_table(
        "evaluation_runs",
        sa.Column("evaluation_id", sa.Integer(), nullable=False),
        sa.Column("slot", sa.Integer(), nullable=False, autoincrement=False),
        sa.Column("run_id", sa.Integer(), nullable=False),
        sa.Column("advised", sa.Boolean(), nullable=False),
        sa.Column("step", sa.BigInteger(), nullable=False),
        sa.ForeignKeyConstraint(
            ["evaluation_id"],
            ["evaluations.id"],
            name="fk_evaluation_runs_evaluation_id_evaluations",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["run_id"], ["runs.id"], name="fk_evaluation_runs_run_id_runs", ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("evaluation_id", "slot", name="pk_evaluation_runs"),
    )
    op.create_index("ix_evaluation_runs_run_id", "evaluation_runs", ["run_id"])
    op.create_table(
        "evaluation_stimuli",
        sa.Column("evaluation_id", sa.Integer(), nullable=False),
        sa.Column("slot", sa.Integer(), nullable=False, autoincrement=False),
        sa.Column("window", sa.Integer(), nullable=False, autoincrement=False),
        sa.Column("still_path", sa.String(255), nullable=False),
        sa.Column("clip_path", sa.String(255), nullable=True),
        sa.ForeignKeyConstraint(
            ["evaluation_id"],
            ["evaluations.id"],
            name="fk_evaluation_stimuli_evaluation_id_evaluations",
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("evaluation_id", "slot", "window", name="pk_evaluation_stimuli"),
    )


def _create_evaluators() -> None:
    op.create_table(
        "evaluators",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("sequence_index", sa.Integer(), nullable=False),
        sa.Column("excluded", sa.Boolean(), nullable=False),
        sa.ForeignKeyConstraint(
            ["id"], ["members.id"], name="fk_evaluators_id_members", ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name="pk_evaluators"),
    )


def _create_pairs() -> None:
    op.create_table(
        "evaluation_pairs",
        sa.Column("evaluator_id", sa.Integer(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False, autoincrement=False),
        sa.Column("key", sa.String(32), nullable=False),
        sa.Column("a", sa.Integer(), nullable=False),
        sa.Column("b", sa.Integer(), nullable=False),
        sa.Column("window_a", sa.Integer(), nullable=False),
        sa.Column("window_b", sa.Integer(), nullable=False),
        sa.Column("a_left", sa.Boolean(), nullable=False),
        sa.Column("winner", sa.Integer(), nullable=True),
        sa.Column("tie", sa.Boolean(), nullable=False),
        sa.Column("chose_left", sa.Boolean(), nullable=True),
        sa.Column("response_ms", sa.BigInteger(), nullable=True),
        sa.Column("stimulus", sa.String(8), nullable=True),
        sa.Column("reminder", sa.Boolean(), nullable=True),
        sa.Column("answered_at", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(
            ["evaluator_id"],
            ["evaluators.id"],
            name="fk_evaluation_pairs_evaluator_id_evaluators",
            ondelete="CASCADE",
        ),
        sa.CheckConstraint("a <> b", name="ck_evaluation_pairs_distinct_runs"),
        sa.CheckConstraint(
            "response_ms IS NULL OR response_ms >= 0", name="ck_evaluation_pairs_response_ms"
        ),
        sa.PrimaryKeyConstraint("evaluator_id", "position", name="pk_evaluation_pairs"),
        sa.UniqueConstraint("key", name="uq_evaluation_pairs_key"),
    )


def downgrade() -> None:
    for table in ("evaluation_pairs", "evaluators", "evaluation_stimuli", "evaluation_runs"):
        op.drop_table(table)
    op.drop_table("evaluations")
    op.execute("DELETE FROM open_links WHERE collection_kind = 'evaluation'")
    op.execute("DELETE FROM members WHERE collection_kind = 'evaluation'")
    _kinds(_KINDS_BEFORE, drop=_NEW_NAME, create=_OLD_NAME)
