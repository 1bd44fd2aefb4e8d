"""The one CSV writer of every export the app serves (labels, crowd labels, survey answers,
conformance): a text cell that a spreadsheet would run as a formula is neutralised.

Per OWASP's "CSV Injection" advice, a cell that starts with ``=``, ``+``, ``-``, ``@``, a
tab or a carriage return gets a leading ``'``, so the spreadsheet shows it as text. Only
strings are touched: numbers (a negative Kendall tau, say) stay numbers. JSON exports keep
the values as given.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def safe_cell(value: Any) -> Any:
    """``value``, with a leading ``'`` if it is text a spreadsheet would run as a formula."""
    return f"'{value}" if isinstance(value, str) and value.startswith(FORMULA_STARTS) else value


def csv_text(header: Sequence[str], rows: Iterable[Sequence[Any] | Mapping[str, Any]]) -> str:
    """CSV with ``header``; each row a sequence in header order or a mapping by column name.

    Args:
        header: The column names (written as the first line).
        rows: The rows; a mapping may leave a column out (an empty cell).

    Returns:
        The CSV text, ``\\n`` line endings, every text cell passed through :func:`safe_cell`.
    """
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([safe_cell(h) for h in header])
    for row in rows:
        cells = [row.get(h) for h in header] if isinstance(row, Mapping) else row
        writer.writerow([safe_cell(c) for c in cells])
    return out.getvalue()
