"""Clips in ordinary studies and gold, practice and the gate for evaluations (issue 41).

- ``studies.clips``: the researcher opted in to motion clips (off by default);
  ``studies.clips_ready``: every candidate's clip is rendered (stills show until then).
- ``candidates.clip_path``: the candidate's clip, rolled forward from its state;
  ``candidates.clip_policy`` and ``candidates.clip_seed``: the policy that rolled it and the
  seed of its reset, recorded with the clip.
- ``labels.stimulus``: what the pair showed, ``still`` or ``clip``; every earlier label
  answered two stills.
- ``evaluations.gold_pairs`` (instructed pairs per evaluator), ``evaluations.practice_pairs``
  (practice before the first pair) and ``evaluations.gold_gate`` (the gate: ``NULL``, none).
- ``evaluation_pairs.gold_answer``: on a gold pair, the slot shown with the marker
  (``NULL``: a real pair); ``evaluators.exclusion_reason``: why an evaluator is left out.

Plain ``ADD COLUMN``s: every row is kept.

Revision ID: 0020
Revises: 0019
Create Date: 2026-11-28
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0020"
down_revision: str | None = "0019"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_COLUMNS: tuple[tuple[str, sa.Column], ...] = (
    ("studies", sa.Column("clips", sa.Boolean(), nullable=False, server_default=sa.false())),
    ("studies", sa.Column("clips_ready", sa.Boolean(), nullable=False, server_default=sa.false())),
    ("candidates", sa.Column("clip_path", sa.String(255), nullable=True)),
    ("candidates", sa.Column("clip_policy", sa.String(100), nullable=True)),
    ("candidates", sa.Column("clip_seed", sa.BigInteger(), nullable=True)),
    ("labels", sa.Column("stimulus", sa.String(8), nullable=False, server_default="still")),
    ("evaluations", sa.Column("gold_pairs", sa.Integer(), nullable=False, server_default="0")),
    ("evaluations", sa.Column("practice_pairs", sa.Integer(), nullable=False, server_default="0")),
    ("evaluations", sa.Column("gold_gate", sa.Float(), nullable=True)),
    ("evaluation_pairs", sa.Column("gold_answer", sa.Integer(), nullable=True)),
    ("evaluators", sa.Column("exclusion_reason", sa.String(200), nullable=True)),
)


def upgrade() -> None:
    for table, column in _COLUMNS:
        op.add_column(table, column)


def downgrade() -> None:
    for table, column in reversed(_COLUMNS):
        with op.batch_alter_table(table) as batch:
            batch.drop_column(column.name)
