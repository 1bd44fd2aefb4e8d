"""One ``members`` table and one ``open_links`` table (issue 43 §1).

- ``members`` holds every person of every collection: ``collection_kind`` (``study``,
  ``survey``), ``collection_id`` and the columns both kinds had. ``participants`` and
  ``survey_respondents`` keep only their own columns, keyed by the member's id (joined-table
  inheritance).
- Participants keep their ids: dataset pseudonyms are an HMAC of the id, and ids are in URLs,
  CSVs and webhook payloads. Respondents get ids above the largest participant id (their
  old id plus that largest id, so their order is kept); ``survey_respondents.former_id``
  records the old id, which exports, payloads and screen plans go on showing and using.
- ``open_links`` holds both kinds' links, ``study_link_options`` a study link's quality
  options; ``crowd_settings`` and ``survey_crowd_settings`` are copied into them and dropped.

SQLite rebuilds a table to drop its columns: ``migrations/env.py`` turns foreign keys off
for the migration (a dropped table would otherwise delete its children's rows) and checks
every reference once it is done. PostgreSQL alters in place, and drops the foreign keys into
``survey_respondents`` while respondents are renumbered.

The downgrade restores both layouts, respondents' old ids included (a respondent who joined
after the upgrade keeps the id the upgrade gave them).

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-27
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0017"
down_revision: str | None = "0016"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: The columns both kinds of member had, now the members table's.
SHARED = (
    "token",
    "token_hash",
    "name",
    "created_at",
    "finished_at",
    "external_id",
    "external_ids",
    "via_link",
    "share_consent",
)
#: The columns both kinds of open link had, now the open_links table's.
LINK = (
    "slug",
    "enabled",
    "max_participants",
    "joined",
    "declines",
    "external_params",
    "consent_text",
    "completion_code",
    "redirect_url",
)
STUDY_OPTIONS = ("consistency_check", "speed_threshold_ms", "gold_gate", "gate_excludes")
#: Each member table, its collection column and the collection's table.
KINDS = (("participants", "study_id", "studies"), ("survey_respondents", "survey_id", "surveys"))
#: The tables that name a respondent, by ``respondent_id``.
RESPONDENT_CHILDREN = ("survey_screens", "survey_answers")
_KIND_CHECK = "collection_kind IN ('study', 'survey')"
_COUNTS = "max_participants >= 1 AND joined >= 0 AND joined <= max_participants AND declines >= 0"


def _postgres() -> bool:
    return op.get_bind().dialect.name == "postgresql"


def _member_columns() -> list[sa.Column]:
    return [
        sa.Column("token", sa.String(64), nullable=False),
        sa.Column("token_hash", sa.String(64), nullable=False),
        sa.Column("name", sa.String(200), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("external_id", sa.String(200), nullable=True),
        sa.Column("external_ids", sa.JSON(), nullable=True),
        sa.Column("via_link", sa.Boolean(), nullable=False),
        sa.Column("share_consent", sa.Boolean(), nullable=False),
    ]


def _link_columns() -> list[sa.Column]:
    return [
        sa.Column("slug", sa.String(64), nullable=False),
        sa.Column("enabled", sa.Boolean(), nullable=False),
        sa.Column("max_participants", sa.Integer(), nullable=False),
        sa.Column("joined", sa.Integer(), nullable=False),
        sa.Column("declines", sa.Integer(), nullable=False),
        sa.Column("external_params", sa.JSON(), nullable=False),
        sa.Column("consent_text", sa.Text(), nullable=True),
        sa.Column("completion_code", sa.String(100), nullable=True),
        sa.Column("redirect_url", sa.String(500), nullable=True),
    ]


def _study_option_columns() -> list[sa.Column]:
    return [
        sa.Column("consistency_check", sa.Boolean(), nullable=False),
        sa.Column("speed_threshold_ms", sa.Integer(), nullable=False),
        sa.Column("gold_gate", sa.Float(), nullable=True),
        sa.Column("gate_excludes", sa.Boolean(), nullable=False),
    ]


def upgrade() -> None:
    _create_members()
    offset = op.get_bind().scalar(sa.text("SELECT coalesce(max(id), 0) FROM participants"))
    _copy_members("participants", "study", "study_id", "id")
    _copy_members("survey_respondents", "survey", "survey_id", f"id + {int(offset)}")
    _sequence_past_ids("members")
    _renumber_respondents(int(offset))
    for table, owner, collections in KINDS:
        _keep_own_columns(table, owner, collections)
    _merge_links()


def _create_members() -> None:
    op.create_table(
        "members",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("collection_kind", sa.String(16), nullable=False),
        sa.Column("collection_id", sa.Integer(), nullable=False),
        *_member_columns(),
        sa.PrimaryKeyConstraint("id", name="pk_members"),
        sa.CheckConstraint(_KIND_CHECK, name="ck_members_collection_kind"),
        sa.UniqueConstraint("token", name="uq_members_token"),
    )
    op.create_index("ix_members_token_hash", "members", ["token_hash"], unique=True)
    op.create_index("ix_members_collection", "members", ["collection_kind", "collection_id"])
    op.create_index(
        "uq_members_collection_external_id",
        "members",
        ["collection_kind", "collection_id", "external_id"],
        unique=True,
    )


def _copy_members(table: str, kind: str, owner: str, new_id: str) -> None:
    shared = ", ".join(SHARED)
    op.execute(
        f"INSERT INTO members (id, collection_kind, collection_id, {shared}) "
        f"SELECT {new_id}, '{kind}', {owner}, {shared} FROM {table} ORDER BY id"
    )


def _sequence_past_ids(table: str) -> None:
    """PostgreSQL: the table's id sequence continues past the ids copied in."""
    if _postgres():
        op.execute(
            f"SELECT setval(pg_get_serial_sequence('{table}', 'id'), "
            f"coalesce((SELECT max(id) FROM {table}), 0) + 1, false)"
        )


def _renumber_respondents(offset: int) -> None:
    """Each respondent's id plus ``offset``, in their table and every table naming them; the
    old id kept in ``former_id``. Through negative ids first: PostgreSQL checks a unique key
    row by row, and a shifted id may still be another row's."""
    op.add_column("survey_respondents", sa.Column("former_id", sa.Integer(), nullable=True))
    _respondent_references(drop=True)
    op.execute("UPDATE survey_respondents SET former_id = id, id = -id")
    op.execute(f"UPDATE survey_respondents SET id = former_id + {offset}")
    for child in RESPONDENT_CHILDREN:
        op.execute(f"UPDATE {child} SET respondent_id = -respondent_id")
        op.execute(f"UPDATE {child} SET respondent_id = {offset} - respondent_id")
    _respondent_references(drop=False)
    with op.batch_alter_table("survey_respondents") as batch:
        batch.create_unique_constraint("uq_survey_respondents_former_id", ["former_id"])


def _respondent_references(*, drop: bool) -> None:
    """PostgreSQL: drop (or add back) the foreign keys into ``survey_respondents``. SQLite
    runs this revision with foreign keys off, and keeps them as they are."""
    if not _postgres():
        return
    for child in RESPONDENT_CHILDREN:
        name = f"fk_{child}_respondent_id_survey_respondents"
        if drop:
            op.drop_constraint(name, child, type_="foreignkey")
        else:
            op.create_foreign_key(
                name, child, "survey_respondents", ["respondent_id"], ["id"], ondelete="CASCADE"
            )


def _keep_own_columns(table: str, owner: str, collections: str) -> None:
    """Drop the member columns from ``table``; its id becomes a reference to the member."""
    for index in (f"ix_{table}_{owner}", f"ix_{table}_token_hash"):
        op.drop_index(index, table_name=table)
    op.drop_index(f"uq_{table}_{owner.removesuffix('_id')}_external_id", table_name=table)
    with op.batch_alter_table(table) as batch:
        batch.drop_constraint(f"fk_{table}_{owner}_{collections}", type_="foreignkey")
        batch.drop_constraint(f"uq_{table}_token", type_="unique")
        for column in (owner, *SHARED):
            batch.drop_column(column)
        batch.create_foreign_key(
            f"fk_{table}_id_members", "members", ["id"], ["id"], ondelete="CASCADE"
        )
    if _postgres():  # ids now come from the members table's sequence
        op.execute(f"ALTER TABLE {table} ALTER COLUMN id DROP DEFAULT")
        op.execute(f"DROP SEQUENCE IF EXISTS {table}_id_seq")


def _merge_links() -> None:
    op.create_table(
        "open_links",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("collection_kind", sa.String(16), nullable=False),
        sa.Column("collection_id", sa.Integer(), nullable=False),
        *_link_columns(),
        sa.PrimaryKeyConstraint("id", name="pk_open_links"),
        sa.CheckConstraint(_KIND_CHECK, name="ck_open_links_collection_kind"),
        sa.CheckConstraint(_COUNTS, name="ck_open_links_counts"),
        sa.UniqueConstraint("slug", name="uq_open_links_slug"),
    )
    op.create_index(
        "uq_open_links_collection", "open_links", ["collection_kind", "collection_id"], unique=True
    )
    op.create_table(
        "study_link_options",
        sa.Column("id", sa.Integer(), nullable=False),
        *_study_option_columns(),
        sa.PrimaryKeyConstraint("id", name="pk_study_link_options"),
        sa.CheckConstraint("speed_threshold_ms >= 0", name="ck_study_link_options_speed"),
        sa.ForeignKeyConstraint(
            ["id"],
            ["open_links.id"],
            name="fk_study_link_options_id_open_links",
            ondelete="CASCADE",
        ),
    )
    link = ", ".join(LINK)
    for table, kind, owner in (
        ("crowd_settings", "study", "study_id"),
        ("survey_crowd_settings", "survey", "survey_id"),
    ):
        op.execute(
            f"INSERT INTO open_links (collection_kind, collection_id, {link}) "
            f"SELECT '{kind}', {owner}, {link} FROM {table} ORDER BY {owner}"
        )
    options = ", ".join(STUDY_OPTIONS)
    op.execute(
        f"INSERT INTO study_link_options (id, {options}) "
        f"SELECT o.id, {', '.join(f'c.{c}' for c in STUDY_OPTIONS)} FROM crowd_settings c "
        "JOIN open_links o ON o.collection_kind = 'study' AND o.collection_id = c.study_id"
    )
    op.drop_table("crowd_settings")
    op.drop_table("survey_crowd_settings")


def downgrade() -> None:
    _split_links()
    for table, owner, collections in reversed(KINDS):
        _restore_member_columns(table, owner, collections)
    _restore_respondent_ids()
    op.drop_table("members")


def _split_links() -> None:
    link = ", ".join(LINK)
    for table, kind, owner, collections, options in (
        ("crowd_settings", "study", "study_id", "studies", STUDY_OPTIONS),
        ("survey_crowd_settings", "survey", "survey_id", "surveys", ()),
    ):
        extra = _study_option_columns() if options else []
        checks = [sa.CheckConstraint("speed_threshold_ms >= 0", name="ck_crowd_settings_speed")]
        op.create_table(
            table,
            sa.Column(owner, sa.Integer(), nullable=False),
            *_link_columns(),
            *extra,
            sa.PrimaryKeyConstraint(owner, name=f"pk_{table}"),
            sa.CheckConstraint(_COUNTS, name=f"ck_{table}_counts"),
            *(checks if options else []),
            sa.ForeignKeyConstraint(
                [owner],
                [f"{collections}.id"],
                name=f"fk_{table}_{owner}_{collections}",
                ondelete="CASCADE",
            ),
            sa.UniqueConstraint("slug", name=f"uq_{table}_slug"),
        )
        selected = ", ".join([*(f"o.{c}" for c in LINK), *(f"s.{c}" for c in options)])
        join = "JOIN study_link_options s ON s.id = o.id " if options else ""
        op.execute(
            f"INSERT INTO {table} ({owner}, {link}{''.join(f', {c}' for c in options)}) "
            f"SELECT o.collection_id, {selected} FROM open_links o {join}"
            f"WHERE o.collection_kind = '{kind}'"
        )
    op.drop_table("study_link_options")
    op.drop_table("open_links")


def _restore_member_columns(table: str, owner: str, collections: str) -> None:
    """The member columns back on ``table``, filled from the members table."""
    with op.batch_alter_table(table) as batch:
        batch.drop_constraint(f"fk_{table}_id_members", type_="foreignkey")
        for column in (sa.Column(owner, sa.Integer(), nullable=True), *_member_columns()):
            batch.add_column(sa.Column(column.name, column.type, nullable=True))
    for column in (owner, *SHARED):
        source = "collection_id" if column == owner else column
        op.execute(
            f"UPDATE {table} SET {column} = "
            f"(SELECT m.{source} FROM members m WHERE m.id = {table}.id)"
        )
    required = {c.name: c for c in _member_columns() if not c.nullable}
    with op.batch_alter_table(table) as batch:
        for name in (owner, *required):
            kind = sa.Integer() if name == owner else required[name].type
            batch.alter_column(name, existing_type=kind, nullable=False)
        batch.create_foreign_key(
            f"fk_{table}_{owner}_{collections}", collections, [owner], ["id"], ondelete="CASCADE"
        )
        batch.create_unique_constraint(f"uq_{table}_token", ["token"])
    op.create_index(f"ix_{table}_{owner}", table, [owner])
    op.create_index(f"ix_{table}_token_hash", table, ["token_hash"], unique=True)
    op.create_index(
        f"uq_{table}_{owner.removesuffix('_id')}_external_id",
        table,
        [owner, "external_id"],
        unique=True,
    )
    if _postgres():  # an id sequence of its own again
        op.execute(f"CREATE SEQUENCE {table}_id_seq OWNED BY {table}.id")
        op.execute(f"ALTER TABLE {table} ALTER COLUMN id SET DEFAULT nextval('{table}_id_seq')")
        _sequence_past_ids(table)


def _restore_respondent_ids() -> None:
    """Each respondent's id as it was before the upgrade (``former_id``), in every table
    naming them, through negative ids as :func:`_renumber_respondents`."""
    _respondent_references(drop=True)
    for child in RESPONDENT_CHILDREN:
        op.execute(
            f"UPDATE {child} SET respondent_id = -(SELECT coalesce(r.former_id, r.id) "
            f"FROM survey_respondents r WHERE r.id = {child}.respondent_id)"
        )
    op.execute("UPDATE survey_respondents SET id = -coalesce(former_id, id)")
    op.execute("UPDATE survey_respondents SET id = -id")
    for child in RESPONDENT_CHILDREN:
        op.execute(f"UPDATE {child} SET respondent_id = -respondent_id")
    _respondent_references(drop=False)
    with op.batch_alter_table("survey_respondents") as batch:
        batch.drop_constraint("uq_survey_respondents_former_id", type_="unique")
        batch.drop_column("former_id")
    _sequence_past_ids("survey_respondents")
