"""``acv worker``: execute queued training runs, standalone (without the web server)."""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from typing import Annotated

import typer

from app.cli.root import cli
from app.cli.serve import migrated_settings, service_errors
from app.core.logs import configure_logging
from app.db import make_engine, make_sessions
from app.jobs.backfill import backfill_all
from app.jobs.settings import JobSettings
from app.jobs.worker import Worker, make_backfiller, make_executor


@cli.command()
def worker(
    slots: Annotated[
        int | None,
        typer.Option(min=1, max=64, help="Runs at the same time (default ACV_WORKER_SLOTS or 1)."),
    ] = None,
    until_idle: Annotated[
        bool, typer.Option(help="Exit once the queue is empty and no run is left.")
    ] = False,
    backfill: Annotated[
        bool,
        typer.Option(
            help="Judge the checkpoints of ended runs that have no stored artefact yet, then exit."
        ),
    ] = False,
) -> None:
    """Claim queued runs and train them: each in its own process, or as Ray tasks when
    ACV_RAY_ADDRESS is set. Ctrl-C (or SIGTERM) stops the runs after a checkpoint; they
    become `interrupted` and can be resumed."""
    settings = migrated_settings()
    jobs = JobSettings()
    if backfill:
        _backfill(settings.sqlalchemy_url, jobs.runs_root(settings))
        return
    configure_logging(settings.log_format)  # the worker's own lines: runs claimed, ended
    with service_errors():
        engine = make_engine(settings.sqlalchemy_url)
        sessions = make_sessions(engine)
        runner = Worker(
            sessions,
            make_executor(settings, jobs),
            slots=slots or jobs.worker_slots,
            poll_s=jobs.poll_s,
            backfill=make_backfiller(sessions, settings, jobs),
        )
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    typer.echo(
        f"acv worker {runner.id}: {runner.executor.name} executor, {runner.slots} "
        f"slot(s), runs in {jobs.runs_root(settings).resolve()}"
    )
    try:
        runner.run(stop, until_idle=until_idle)
    finally:
        engine.dispose()


def _backfill(url: str, runs_root: Path) -> None:
    """Compute the missing checkpoint artefacts of ended runs, in this process."""
    engine = make_engine(url)
    try:
        done = backfill_all(make_sessions(engine), runs_root=runs_root)
    finally:
        engine.dispose()
    typer.echo(f"acv worker --backfill: {done} checkpoint artefact(s) stored")
