"""The ``acv`` Typer application that every command module registers on."""

from __future__ import annotations

import sys
from typing import NoReturn

import typer

cli = typer.Typer(
    name="acv",
    help="Advice Conformance Verification: human vs agent preference trees.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def fail(message: str) -> NoReturn:
    """Print one clear line on stderr and exit with code 2 (bad input)."""
    print(f"acv: error: {message}", file=sys.stderr)
    raise typer.Exit(code=2)
