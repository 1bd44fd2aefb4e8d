"""Services every feature shares: their errors (each maps to one HTTP status),
credentials, the CSV writer and static figures.

Service functions take a :class:`~sqlalchemy.orm.Session` and keyword-only arguments, raise
:class:`~engine.errors.InputError` (bad input) or an :mod:`app.core.errors` exception, and
commit their own writes (through :func:`app.db.writing`).
"""
