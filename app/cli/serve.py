"""``acv serve``: apply migrations, then serve the web app with uvicorn.

With ``--workers N`` (N > 1) uvicorn's supervisor starts N server processes (spawned, each
building its app with :func:`worker_app`) that share the listening socket. The work that
must happen once happens in the supervisor, before and beside them: the migrations, the
admin token, resuming half-prepared studies, the training-run worker and webhook delivery
(threads). The server processes share the database (SQLite in WAL mode, writers queued on a
file lock; see :mod:`app.db`), with the failed-login counts in it (:mod:`app.http.lockouts`),
and the open-link join counts (:mod:`app.http.ratelimit`); researcher and participant
cookies are signed or looked up, never kept in a process.
"""

from __future__ import annotations

import gc
import logging.config
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Annotated, Any

import typer
import uvicorn
from fastapi import FastAPI
from pydantic import ValidationError
from sqlalchemy.exc import ArgumentError, SQLAlchemyError

from app.cli.root import cli, fail, validation_errors
from app.core.auth import ADMIN_TOKEN_FILE
from app.core.errors import ServiceError
from app.core.logs import log_config
from app.db import upgrade
from app.demo import ensure_demo
from app.jobs.settings import JobSettings
from app.jobs.worker import Worker, WorkerThread, make_executor
from app.labelling.participants import invite_url
from app.main import create_app
from app.preflight import check_data_dir
from app.runtime import Runtime
from app.settings import Settings
from app.webhooks.scheduler import start_delivery
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
        fail(f"bad setting: {validation_errors(exc)}")
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


#: Tells the spawned server processes how many they are (an internal variable).
WORKERS_ENV = "ACV_SERVE_WORKERS"


@cli.command()
def serve(
    host: Annotated[str, typer.Option(help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="TCP port.")] = 8000,
    demo: Annotated[
        bool,
        typer.Option(
            help="Prepare a demo study first (16 Humanoid-v5 states, one simulated participant)."
        ),
    ] = False,
    access_log: Annotated[bool, typer.Option(help="Log every request.")] = True,
    workers: Annotated[
        int,
        typer.Option(
            min=1,
            max=64,
            help="Server processes (one per CPU core for crowds of labellers; see the README).",
        ),
    ] = 1,
) -> None:
    """Apply database migrations, print the researcher login URL, and serve the app."""
    settings = migrated_settings()
    logs = log_config(settings.log_format, workers)
    logging.config.dictConfig(logs)  # the app's lines from here on, uvicorn's too
    with service_errors():
        app = create_app(settings) if workers == 1 else None
        runtime: Runtime = app.state.runtime if app is not None else Runtime(settings)
        base = base_url(settings, host, port)
        demo_lines = _demo_lines(runtime, base) if demo else []
    _print_welcome(settings, runtime, base, workers, demo_lines)
    options: dict[str, Any] = {
        "host": host,
        "port": port,
        "access_log": access_log,
        "log_level": "info",
        "timeout_graceful_shutdown": 10,
        # The app trusts forwarded headers itself, from ACV_FORWARDED_ALLOW_IPS only
        # (app.main); uvicorn's own handling would believe any local client.
        "proxy_headers": False,
        "log_config": logs,
    }
    if app is not None:
        tune_gc()
        uvicorn.run(app, **options)
    else:
        _serve_workers(runtime, workers, options)


def _print_welcome(
    settings: Settings, runtime: Runtime, base: str, workers: int, demo_lines: list[str]
) -> None:
    """Where the app is, its data and database, how to log in, the demo's links, the docs."""
    typer.echo(
        f"ACV on {base}  (data: {settings.data_dir.resolve()}, database: "
        f"{runtime.engine.url.render_as_string(hide_password=True)}"
        f"{f', {workers} server processes' if workers > 1 else ''})"
    )
    for line in [*_login_lines(settings, runtime.admin_token, base), *demo_lines]:
        typer.echo(line)
    typer.echo(f"  API docs:         {base}/docs")


def _serve_workers(runtime: Runtime, workers: int, options: dict[str, Any]) -> None:
    """N spawned server processes under uvicorn's supervisor; the background work runs here,
    once."""
    os.environ[WORKERS_ENV] = str(workers)
    runtime.resume()
    jobs = JobSettings()
    run_worker = (
        WorkerThread(
            Worker(
                runtime.sessions,
                make_executor(runtime.settings, jobs),
                slots=jobs.worker_slots,
                poll_s=jobs.poll_s,
            )
        ).start()
        if jobs.run_worker
        else None
    )
    webhooks = start_delivery(runtime.sessions, runtime.settings)
    try:
        uvicorn.run("app.cli.serve:worker_app", factory=True, workers=workers, **options)
    finally:
        webhooks.stop()
        if run_worker is not None:
            run_worker.stop()  # running runs checkpoint and become `interrupted`
        runtime.close()


def worker_app() -> FastAPI:
    """The app of one of ``acv serve --workers N``'s processes: settings from the
    environment, the database already migrated, no background work (the supervisor's)."""
    tune_gc()
    return create_app(Settings(), background=False, processes=int(os.environ.get(WORKERS_ENV, "1")))


def tune_gc() -> None:
    """Fewer and shorter garbage-collection pauses while serving (they showed in the tail
    latency of labelling, issue 16): objects alive at start-up (modules, the ORM's mappers,
    routes) are frozen out of collection, and collections start less often (request garbage
    is freed by reference counting; only cycles wait for the collector)."""
    gc.collect()
    gc.freeze()
    gc.set_threshold(10_000, 20, 20)


def _login_lines(settings: Settings, admin_token: str, base: str) -> list[str]:
    """How to log in. A configured token (ACV_ADMIN_TOKEN) is never printed: this output
    often ends up in journald or docker logs. A generated one is, in a URL fragment (which
    browsers never send, so it stays out of access logs); it is kept in the data dir."""
    if settings.admin_token is not None:
        return [f"  researcher login: {base}/login  (with the admin token set in ACV_ADMIN_TOKEN)"]
    return [
        f"  researcher login: {base}/login#token={admin_token}",
        f"  admin token:      {admin_token}  (kept in "
        f"{(settings.data_dir / ADMIN_TOKEN_FILE).resolve()})",
    ]


def _demo_lines(runtime: Runtime, base: str) -> list[str]:
    typer.echo("preparing the demo study (sampling and rendering 16 states)...")
    demo = ensure_demo(runtime)
    return [
        f"  demo study:       {base}/studies/{demo.study.id}  (id {demo.study.id})",
        f"  participant link: {invite_url(base, demo.invite_token)}",
        f"  demo experiment:  {base}/experiments/{demo.experiment_id}  (its 12 runs train in "
        "the background; the verdict comes in about 7 minutes on two cores)",
    ]
