"""Response models filled from database rows."""

from __future__ import annotations

from typing import Any, TypeVar

from pydantic import BaseModel

Model = TypeVar("Model", bound=BaseModel)


def from_row(model: type[Model], row: object, **computed: Any) -> Model:
    """``model`` validated from ``row``'s attributes of the same names, and ``computed`` for
    the fields that are not columns (a URL, a count).

    Pydantic's ``from_attributes`` reads the whole object and takes no extra values, so the
    columns are picked here, then validated with the computed fields as one mapping.
    """
    columns = {
        name: getattr(row, name)
        for name in model.model_fields
        if name not in computed and hasattr(row, name)
    }
    return model.model_validate(columns | computed)
