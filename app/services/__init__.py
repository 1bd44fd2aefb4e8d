"""The service layer: everything the REST API, the pages and the CLI do with the database.

Functions take a :class:`~sqlalchemy.orm.Session` and keyword-only arguments, raise
:class:`~engine.errors.InputError` (bad input) or an :mod:`app.services.errors` exception,
and commit their own writes (through :func:`app.db.writing`).
"""
