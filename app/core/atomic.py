"""Writes that hold under concurrency, enforced by the database, never by check-then-insert
(issue 45 §4): every feature's limits and shared rows go through these.

- :func:`take` and :func:`give_back`: a counter column capping how many rows of a kind one
  owner may have (an open link's seats, a study's webhooks or gold items), moved by one
  ``UPDATE ... SET n = n + 1 WHERE ... AND n < limit``, whose row count says whether it did.
  PostgreSQL's row lock and SQLite's single writer order concurrent takes, and each one sees
  the count the one before it left, so the limit is never passed.
- :func:`insert_or_nothing`: ``INSERT ... ON CONFLICT DO NOTHING`` on a unique index, for a
  row that concurrent writers may all try to create: one stores it, the others see it.

Each runs inside the caller's write transaction (:func:`app.db.writing`): the counter moves
with the rows it counts, or not at all.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

from sqlalchemy import ColumnElement, CursorResult, Insert, insert, update
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import InstrumentedAttribute, Session


def take(
    session: Session,
    counter: InstrumentedAttribute[int],
    owner: ColumnElement[bool],
    *,
    limit: int | ColumnElement[int] | InstrumentedAttribute[int],
) -> bool:
    """Add one to ``counter`` on the row ``owner`` selects while it is below ``limit`` (a
    number, or another column of the row); whether it did.

    Args:
        session: inside the caller's write transaction.
        counter: the counter column (``Study.webhook_count``).
        owner: selects the owner's row (``Study.id == 3``).
        limit: the largest count.
    """
    result = session.execute(
        update(counter.class_).where(owner, counter < limit).values({counter: counter + 1})
    )
    return cast(CursorResult[Any], result).rowcount > 0


def give_back(
    session: Session, counter: InstrumentedAttribute[int], owner: ColumnElement[bool]
) -> None:
    """Take one from ``counter`` on the row ``owner`` selects (never below 0), inside the
    caller's write transaction: a counted row was removed."""
    session.execute(update(counter.class_).where(owner, counter > 0).values({counter: counter - 1}))


def insert_or_nothing(
    session: Session,
    model: type[Any],
    *,
    index_elements: Sequence[InstrumentedAttribute[Any]],
    index_where: ColumnElement[bool] | None = None,
) -> Insert:
    """``INSERT INTO model ... ON CONFLICT (index_elements) [WHERE index_where] DO NOTHING``
    for this session's database (add ``.values()`` and, to learn whether a row was stored,
    ``.returning()``): a row whose unique key is taken is skipped, not an error. On
    PostgreSQL a conflicting row that is not committed yet makes it wait for that row's
    transaction, so the caller's next statement sees the row once it is there.

    Args:
        index_elements: the unique index's columns.
        index_where: a partial index's condition, the same as the index's.
    """
    dialect = session.get_bind().dialect.name
    if dialect == "postgresql":
        return postgresql.insert(model).on_conflict_do_nothing(
            index_elements=index_elements, index_where=index_where
        )
    if dialect == "sqlite":
        return sqlite.insert(model).on_conflict_do_nothing(
            index_elements=index_elements, index_where=index_where
        )
    return insert(model)  # no other database is supported; kept plain
