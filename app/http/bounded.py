"""Error answers and log lines of bounded size and depth, whatever the request held.

FastAPI's 422 lists each error with the offending ``input``: for a deep body that is a deep
value (whose encoding overflowed the stack: a 500), and for a wide one a copy of the body
(a 3 KB request answered, and logged, in 168 KB). Here each error keeps its type, location,
message and scalar context; an ``input`` only when it is a short scalar; at most
:data:`MAX_ERRORS` errors. Nothing recurses into the request's values.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

#: Errors listed in one answer; the rest are counted in a last entry.
MAX_ERRORS = 10
#: Characters kept of a message, a location part or a string input.
MAX_TEXT = 500
#: Parts kept of a location (``["body", "a", "a", ...]``).
MAX_LOC = 12


def text(value: str, limit: int = MAX_TEXT) -> str:
    """``value`` cut to ``limit`` characters (marked with ``...``), valid UTF-8 (a lone
    surrogate, ``"\\ud800"`` in JSON, becomes ``?``)."""
    cut = value if len(value) <= limit else value[:limit] + "..."
    return cut.encode("utf-8", "replace").decode("utf-8")


def scalar(value: Any) -> Any:
    """A JSON scalar that is short and valid as JSON, or ``None`` for anything else
    (containers, objects, long numbers)."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if isinstance(value, int):
        return value if abs(value) < 2**63 else None
    if isinstance(value, str):
        return text(value, 100)
    return None


def errors(items: Sequence[Any]) -> list[dict[str, Any]]:
    """Pydantic's error list, bounded: see the module's docstring."""
    out = [_error(e) for e in items[:MAX_ERRORS]]
    if len(items) > MAX_ERRORS:
        out.append({"type": "too_many_errors", "loc": [], "msg": f"{len(items) - MAX_ERRORS} more"})
    return out


def _error(e: Any) -> dict[str, Any]:
    out: dict[str, Any] = {
        "type": text(str(e.get("type", "")), 100),
        "loc": _loc(e.get("loc", ())),
        "msg": text(str(e.get("msg", ""))),
    }
    if (given := scalar(e.get("input"))) is not None or e.get("input", 0) is None:
        out["input"] = given
    ctx = {str(k): scalar(v) for k, v in (e.get("ctx") or {}).items()}
    if ctx := {k: v for k, v in ctx.items() if v is not None}:
        out["ctx"] = ctx
    return out


def _loc(loc: Any) -> list[Any]:
    parts = list(loc) if isinstance(loc, tuple | list) else [loc]
    kept = [
        p if isinstance(p, int) and not isinstance(p, bool) else text(str(p), 100) for p in parts
    ]
    return kept if len(kept) <= MAX_LOC else [*kept[:MAX_LOC], "..."]
