"""Limits on what researchers and people may store, shared by every feature's services and
schemas."""

from __future__ import annotations

from engine.errors import InputError

MAX_NAME_CHARS = 200
MAX_INSTRUCTIONS_CHARS = 20_000
#: The widest integer column (seeds, steps): signed 64 bits; SQLite overflows past it.
INT64_MAX = 2**63 - 1
#: Largest database id: ids are positive 32-bit integers (larger ones cannot exist).
MAX_DB_ID = 2**31 - 1
#: Seeds are stored as signed 64-bit integers.
MAX_SEED = INT64_MAX
#: Most members invited in one request.
MAX_BATCH = 500


def check_text(**fields: str | None) -> None:
    """Refuse NUL characters, which PostgreSQL cannot store in text columns."""
    for field, value in fields.items():
        if value is not None and "\x00" in value:
            raise InputError(f"{field} must not contain NUL characters")
