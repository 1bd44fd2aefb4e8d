"""The one integer rule of request input: strict types of JSON bodies, and of path and query
integers, for every feature's schemas.

Bounds go *inside* these types' number schemas, so the OpenAPI document states them as JSON
Schema's ``minimum``/``maximum``/``exclusiveMinimum``/``exclusiveMaximum``. (A validator
function wrapped around ``int`` would leave pydantic nowhere to put a later ``Field(ge=...)``
but a function of its own, which it documents as the non-keywords ``ge``/``le``/``gt``.)
``tests/app/platform/test_strict_integers.py`` walks the OpenAPI document for every rule here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime
from typing import Annotated, Any, TypeVar, get_args

from pydantic import (
    AfterValidator,
    AllowInfNan,
    BaseModel,
    GetCoreSchemaHandler,
    Strict,
    ValidationError,
)
from pydantic.fields import FieldInfo
from pydantic_core import CoreSchema, PydanticCustomError, core_schema

from app.core.limits import INT64_MAX
from app.models import as_utc

M = TypeVar("M", bound=BaseModel)

#: The one rule for an integer of a request body: a JSON integer literal (``3``), never
#: ``3.0``, ``true`` (a JSON ``false`` is not 0), ``"3"`` or ``NaN``. Pydantic's own strict
#: ``int``: its bounds (``Field(ge=...)`` beside it) are JSON Schema's. An HTML form's text
#: ``"3"`` is read by :func:`from_form`. Every integer field of a request body is one.
JsonInt = Annotated[int, Strict()]
#: A JSON number (an integer too), never ``true``, ``"0.5"``, ``NaN`` or ``Infinity``.
JsonFloat = Annotated[float, Strict(), AllowInfNan(False)]
#: Stored times are UTC; SQLite hands them back naive.
UtcDatetime = Annotated[datetime, AfterValidator(as_utc)]

_DIGITS = re.compile(r"0|[1-9][0-9]*")
_SIGNED = re.compile(r"0|-?[1-9][0-9]*")


@dataclass(frozen=True)
class IntParam:
    """The rule for an integer path or query parameter, and its bounds (``Annotated[int,
    IntParam(ge=1, le=9)]``): plain decimal digits, with a leading ``-`` only where ``ge``
    allows negatives. ``1_0``, ``1.0``, ``01``, ``+1``, `` 1``, ``-0`` and ``0x1`` are
    refused (lax parsing reads ``1_0`` as 10 and ``01`` as 1), as a body's integer refuses
    ``"1"``. The bounds belong here, not in ``Path()``/``Query()``, which would put them
    outside the check where OpenAPI cannot state them.

    Attributes:
        ge: the smallest value accepted.
        le: the largest value accepted (every parameter has one: ids and steps are stored in
            64-bit columns at most).
    """

    ge: int
    le: int

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> CoreSchema:
        """An ``int`` schema holding the bounds, behind the check of the text."""
        if source is not int:
            raise TypeError(f"IntParam annotates int, not {source!r}")
        return core_schema.no_info_before_validator_function(
            self._check, core_schema.int_schema(ge=self.ge, le=self.le)
        )

    def _check(self, value: Any) -> Any:
        """``value`` if it is decimal text (or an ``int``, a default); else a 422's error."""
        pattern = _SIGNED if self.ge < 0 else _DIGITS
        if type(value) is int or (isinstance(value, str) and pattern.fullmatch(value)):
            return value
        example = "12 or -1" if self.ge < 0 else "12"
        raise PydanticCustomError(
            "int_digits",
            f"Input should be an integer in plain decimal digits, such as {example} (no '+', "
            "leading zero, space, '_' or '.')",
        )


#: A whole number as a form sends it: optional ``-``, decimal digits, nothing else.
_FORM_INT = re.compile(r"-?[0-9]{1,19}")


def form_int(text: str) -> int | None:
    """An HTML form field's whole number, or None when it is none: decimal digits (a ``-``
    allowed, spaces around ignored) inside 64 bits. Python's ``int()`` would also read
    ``1_0`` as 10 and ``+1`` as 1, and a 30-digit id overflows the database."""
    text = text.strip()
    if not _FORM_INT.fullmatch(text) or abs(value := int(text)) > INT64_MAX:
        return None
    return value


def from_form(model: type[M], data: dict[str, Any]) -> M:
    """An HTML form's fields (``data``, all text) validated as ``model``'s JSON body: there
    ``"3"`` is the integer 3 (a form has no other way to send one), read by :func:`form_int`
    (lax validation alone would take ``1_0`` and ``16.0``); bounds still hold."""
    errors: list[Any] = []
    values = dict(data)
    for name, text in data.items():
        field = model.model_fields.get(name)
        if field is None or not isinstance(text, str) or not text or not _admits_int(field):
            continue
        values[name] = form_int(text)
        if values[name] is None:
            message = "Input should be a whole number in decimal digits, such as 12"
            error = PydanticCustomError("int_digits", message)
            errors.append({"type": error, "loc": (name,), "input": text})
    if errors:
        raise ValidationError.from_exception_data(model.__name__, errors)
    return model.model_validate(values, strict=False)


def _admits_int(field: FieldInfo) -> bool:
    """Whether the field's type is ``int`` or a union holding it (``int | None``)."""
    return field.annotation is int or int in get_args(field.annotation)
