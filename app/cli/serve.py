"""``acv serve``: apply migrations, then serve the web app with uvicorn."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Annotated

import typer
import uvicorn
from pydantic import ValidationError
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from app.cli.root import cli, fail
from app.db import upgrade
from app.main import create_app
from app.preflight import check_data_dir
from app.runtime import Runtime
from app.services.auth import ADMIN_TOKEN_FILE
from app.services.demo import ensure_demo
from app.services.errors import ServiceError
from app.services.participants import invite_url
from app.settings import Settings
from engine.errors import InputError


@contextmanager
def service_errors() -> Iterator[None]:
    """Turn bad input, service and database failures into one stderr line and exit code 2."""
    try:
        yield
    except InputError as exc:
        fail(str(exc))
    except ServiceError as exc:
        fail(exc.detail)
    except ArgumentError as exc:
        fail(f"bad DATABASE_URL: {exc}")
    except ValidationError as exc:  # a setting from the environment
        fail("bad setting: " + "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}"
                                         for e in exc.errors()))
    except SQLAlchemyError as exc:
        fail(f"database error: {str(exc).splitlines()[0]}")


def migrated_settings() -> Settings:
    """The environment's settings, with the database migrated to the latest schema."""
    with service_errors():
        settings = Settings()
        check_data_dir(settings)
        upgrade(settings.sqlalchemy_url)
    return settings


@contextmanager
def cli_runtime() -> Iterator[Runtime]:
    """A :class:`Runtime` on the migrated database, closed afterwards."""
    with service_errors():
        runtime = Runtime(migrated_settings())
        try:
            yield runtime
        finally:
            runtime.close()


def base_url(settings: Settings, host: str, port: int) -> str:
    """Where users reach the server: ``ACV_PUBLIC_URL`` or the listening address."""
    if settings.public_url:
        return settings.public_url.rstrip("/")
    shown = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    return f"http://[{shown}]:{port}" if ":" in shown else f"http://{shown}:{port}"


@cli.command()
def serve(
    host: Annotated[str, typer.Option(help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="TCP port.")] = 8000,
    demo: Annotated[bool, typer.Option(help="Prepare a demo study first (16 Humanoid-v5 "
                                            "states, one simulated participant).")] = False,
    access_log: Annotated[bool, typer.Option(help="Log every request.")] = True,
) -> None:
    """Apply database migrations, print the researcher login URL, and serve the app."""
    settings = migrated_settings()
    with service_errors():
        app = create_app(settings)
        runtime: Runtime = app.state.runtime
        base = base_url(settings, host, port)
        demo_lines = _demo_lines(runtime, base) if demo else []
    typer.echo(f"ACV on {base}  (data: {settings.data_dir.resolve()}, database: "
               f"{runtime.engine.url.render_as_string(hide_password=True)})")
    for line in _login_lines(settings, runtime.admin_token, base):
        typer.echo(line)
    for line in demo_lines:
        typer.echo(line)
    typer.echo(f"  API docs:         {base}/docs")
    uvicorn.run(app, host=host, port=port, access_log=access_log, log_level="info",
                timeout_graceful_shutdown=10)


def _login_lines(settings: Settings, admin_token: str, base: str) -> list[str]:
    """How to log in. A configured token (ACV_ADMIN_TOKEN) is never printed: this output
    often ends up in journald or docker logs. A generated one is, in a URL fragment (which
    browsers never send, so it stays out of access logs); it is kept in the data dir."""
    if settings.admin_token is not None:
        return [f"  researcher login: {base}/login  (with the admin token set in "
                "ACV_ADMIN_TOKEN)"]
    return [f"  researcher login: {base}/login#token={admin_token}",
            f"  admin token:      {admin_token}  (kept in "
            f"{(settings.data_dir / ADMIN_TOKEN_FILE).resolve()})"]


def _demo_lines(runtime: Runtime, base: str) -> list[str]:
    typer.echo("preparing the demo study (sampling and rendering 16 states)...")
    demo = ensure_demo(runtime)
    return [f"  demo study:       {base}/studies/{demo.study.id}  (id {demo.study.id})",
            f"  participant link: {invite_url(base, demo.invite_token)}"]
