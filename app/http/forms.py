"""A researcher's form that was refused is shown again on its own page, as it was sent and
with what was wrong (``templates/_refused.html``), never on a bare error page that loses what
was typed. The open-link form has its own echo (:func:`app.recruiting.pages.form_echo`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from app.core.errors import ConflictError
from app.core.json_types import form_int
from app.core.limits import MAX_BATCH
from engine.errors import InputError

#: What a form's input can be refused for: bad input (422), or a limit it would pass (409).
REFUSED = (InputError, ConflictError)


@dataclass(frozen=True)
class Refused:
    """A refused form: its name in the page, its fields as sent, and the reason."""

    form: str
    fields: dict[str, str]
    error: str


def refused(
    form: str, fields: Mapping[str, str], error: InputError | ConflictError
) -> tuple[dict[str, Any], int]:
    """The page's extra context that shows ``form`` again, and the status to answer with."""
    status = error.status_code if isinstance(error, ConflictError) else 422
    return {"refused": Refused(form, dict(fields), str(error))}, status


def invite_count(fields: Mapping[str, str], people: str) -> int:
    """An invite form's ``count`` (empty: 1).

    Raises:
        InputError: not a whole number in 1..:data:`MAX_BATCH` (``people`` names whom).
    """
    count = form_int(fields.get("count", "").strip() or "1")
    if count is None or not 1 <= count <= MAX_BATCH:
        raise InputError(f"the number of {people} must be a whole number in 1..{MAX_BATCH}")
    return count
