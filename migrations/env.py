"""Alembic environment: runs migrations on the app's database.

The URL comes from ``config.attributes["url"]`` when called through :mod:`app.db`, else from
the app's settings (``DATABASE_URL`` / ``ACV_DATA_DIR``) for the plain ``alembic`` command.
SQLite gets batch mode, since it cannot alter most constraints in place, and runs with
foreign keys off: a batch rebuild drops the old table, and with them on that would delete
the rows of every table referring to it. Every reference is checked once the migrations ran.
"""

from __future__ import annotations

from logging.config import fileConfig

from alembic import context
from sqlalchemy import Connection

from app.db import make_engine, migration_lock
from app.models import Base
from app.settings import Settings

config = context.config
if "url" not in config.attributes and config.config_file_name is not None:
    fileConfig(config.config_file_name, disable_existing_loggers=False)  # CLI use only


def run_migrations_online() -> None:
    url = config.attributes.get("url") or Settings().sqlalchemy_url
    engine = make_engine(url)
    try:
        with engine.connect() as connection:
            sqlite = connection.dialect.name == "sqlite"
            if sqlite:  # only outside a transaction does this pragma take effect
                connection.exec_driver_sql("PRAGMA foreign_keys=OFF")
                connection.commit()
            context.configure(
                connection=connection,
                target_metadata=Base.metadata,
                render_as_batch=sqlite,
                compare_type=True,
            )
            with context.begin_transaction(), migration_lock(connection):
                context.run_migrations()
                if sqlite:
                    _check_references(connection)
    finally:
        engine.dispose()


def _check_references(connection: Connection) -> None:
    """Fail a migration that left a row referring to nothing (SQLite checks no reference
    while foreign keys are off)."""
    broken = connection.exec_driver_sql("PRAGMA foreign_key_check").all()
    if broken:
        raise RuntimeError(f"the migration left rows referring to nothing: {broken[:10]}")


if context.is_offline_mode():
    raise SystemExit("offline (--sql) migrations are not supported; run them online")
run_migrations_online()
