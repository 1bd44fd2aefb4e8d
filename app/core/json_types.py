"""Strict JSON types of request and response bodies, for every feature's schemas."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator, ValidationInfo

from app.models import as_utc

#: Validation context of HTML forms, whose every field is text: there ``"3"`` is an integer.
FORM_INPUT = {"form": True}


def _json_number(kind: str) -> Any:
    def check(value: Any, info: ValidationInfo) -> Any:
        from_form = isinstance(value, str) and bool(info.context and info.context.get("form"))
        if (
            isinstance(value, bool)
            or (isinstance(value, str) and not from_form)
            or (kind == "integer" and isinstance(value, float))
        ):
            # lax pydantic reads true as 1, "3" as 3 and 3.0 as 3
            raise ValueError(f"must be a JSON {kind}")
        return value

    return check


#: The one rule for an integer of a request body: a JSON integer literal (``3``), never
#: ``3.0``, ``true`` (a JSON ``false`` is not 0) or ``"3"``; an HTML form's text ``"3"`` is
#: read with :data:`FORM_INPUT`. Every integer field of a request body is one
#: (``tests/app/test_strict_integers.py`` checks them all, from the OpenAPI document).
JsonInt = Annotated[int, BeforeValidator(_json_number("integer"))]
#: A JSON number (an integer too), never ``true`` or ``"0.5"``.
JsonFloat = Annotated[float, BeforeValidator(_json_number("number"))]
#: Stored times are UTC; SQLite hands them back naive.
UtcDatetime = Annotated[datetime, AfterValidator(as_utc)]
