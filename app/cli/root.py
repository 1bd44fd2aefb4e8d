"""The ``acv`` Typer application that every command module registers on."""

from __future__ import annotations

import json
import sys
from typing import Annotated, Any, NoReturn

import typer
from pydantic import ValidationError
from typer.core import TyperGroup

from engine import __version__
from engine.errors import InputError

# What bad input raises below a command (a file that is not there, not JSON, not a tree;
# a path through a file or too long: every OSError says which path and why).
BAD_INPUT = (InputError, json.JSONDecodeError, OSError, UnicodeDecodeError)


def fail(message: str) -> NoReturn:
    """Print one clear line on stderr and exit with code 2 (bad input)."""
    print(f"acv: error: {message}", file=sys.stderr)
    raise typer.Exit(code=2)


def validation_errors(exc: ValidationError, whole: str = "the input") -> str:
    """A pydantic validation error on one line: each field's path and message (``whole``
    where the error is about the whole input)."""
    return "; ".join(f"{'.'.join(map(str, e['loc'])) or whole}: {e['msg']}" for e in exc.errors())


class _Commands(TyperGroup):
    """The command tree: bad input raised anywhere below a command becomes one line and exit
    code 2 here, so the console script and an in-process invocation answer alike."""

    def invoke(self, ctx: Any) -> Any:  # Typer's vendored click.Context (a private module)
        try:
            return super().invoke(ctx)
        except BAD_INPUT as exc:
            fail(str(exc))
        except OverflowError:  # a number past SQLite's 64-bit integers, where no option bounds it
            fail("a number given is too large for the database")


cli = typer.Typer(
    name="acv",
    cls=_Commands,
    help="Advice Conformance Verification: human vs agent preference trees.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    """``acv --version``: print ``acv <version>`` and exit."""
    if value:
        typer.echo(f"acv {__version__}")
        raise typer.Exit()


@cli.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """The options that come before a command (the help text is the app's)."""
