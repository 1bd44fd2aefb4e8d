"""``acv validate``: the verdict checked on agents whose answer is known (issue 27,
docs/validation.md). Resumable: a second call with the same settings goes on where the first
stopped, and reuses every finished run."""

from __future__ import annotations

import math
import shlex
import sys
import threading
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from app.cli.options import CandidatesOpt, EnvOpt, NEnvsOpt, NumStepsOpt, TeacherOpt
from app.cli.root import cli
from app.cli.serve import service_errors
from engine.envs import check_env_id
from engine.errors import InputError
from engine.validation.design import ARMS, Plan
from engine.validation.workers import Workers

Opt = typer.Option


@cli.command()
def validate(
    out: Annotated[Path, Opt(help="Validation folder (outside the repository).")],
    env: EnvOpt = "Hopper-v5",
    teacher: TeacherOpt = "orthogonal",
    seeds: Annotated[int, Opt(help="Evaluation seeds per arm.")] = 8,
    timesteps: Annotated[int, Opt(help="Env steps per run.")] = 500_000,
    pilot_seeds: Annotated[int, Opt(help="No-advice pilot runs on seeds of their own.")] = 2,
    brackets: Annotated[int, Opt(help="Evaluation brackets (bracket 0 is the advice).")] = 5,
    candidates: CandidatesOpt = 16,
    n_envs: NEnvsOpt = 4,
    num_steps: NumStepsOpt = 512,
    arms: Annotated[
        str, Opt(help=f"Comma-separated arms: {', '.join(a.name for a in ARMS)}.")
    ] = ",".join(a.name for a in ARMS),
    jobs: Annotated[int, Opt(help="Runs trained at once (one core each).")] = 1,
    ray_address: Annotated[
        str | None,
        Opt(
            envvar="ACV_RAY_ADDRESS",
            help="Train and measure each run as a Ray task on this cluster (host:port) "
            "instead of --jobs processes here; this machine must be one of its nodes.",
        ),
    ] = None,
    status: Annotated[
        bool, Opt("--status", help="Say what is measured and training so far; train nothing.")
    ] = False,
    runs: Annotated[
        str | None,
        Opt(
            help="Train only these runs (arm-seed, comma-separated, e.g. n1-2,p1-10-0) and "
            "measure nothing: to share a validation's runs between machines."
        ),
    ] = None,
    stop_after: Annotated[
        float | None,
        Opt(
            help="With --runs: stop each run at a checkpoint after this many minutes (a batch "
            "job's time limit); the next call resumes it exactly where it stopped."
        ),
    ] = None,
) -> None:
    """Train every arm (or reuse finished runs), measure, and write summary.json and
    report.md with each pre-registered criterion under each judge."""
    with service_errors():
        check_env_id(env)
        plan = Plan(
            env_id=env,
            teacher=teacher,
            timesteps=timesteps,
            seeds=seeds,
            pilot_seeds=pilot_seeds,
            brackets=brackets,
            candidates=candidates,
            n_envs=n_envs,
            num_steps=num_steps,
            arms=tuple(a.strip() for a in arms.split(",") if a.strip()),
        )
        if jobs < 1:
            raise InputError(f"--jobs must be at least 1, got {jobs}")
        if status:
            _status(out, plan)
            return
        workers = Workers(jobs, ray_address or None)
        if runs is not None or stop_after is not None:
            _train_only(out, plan, workers, runs, stop_after)
            return
        _run_with_progress(out, plan, workers)
    typer.echo(f"wrote {out / 'summary.json'} and {out / 'report.md'}")


def _status(out: Path, plan: Plan) -> None:
    from engine.validation.runs import PLAN_FILE, prepare
    from engine.validation.validate import status

    if not (out / PLAN_FILE).is_file():
        raise InputError(f"{out} holds no validation yet")
    prepare(out, plan)  # the folder's plan must be these settings' (it writes nothing new)
    for line in status(out, plan):
        typer.echo(line)


def _train_only(
    out: Path, plan: Plan, workers: Workers, runs: str | None, stop_after: float | None
) -> None:
    """Train the named runs (to the end, or for ``stop_after`` minutes) and say how far each
    got; measuring and the summary are left to a call without ``--runs``."""
    from engine.validation.runs import check_advice, parse_tasks, prepare, train_tasks
    from engine.validation.validate import steps_done

    if runs is None:
        raise InputError("--stop-after needs --runs: the runs to train for that long")
    if stop_after is not None and not (math.isfinite(stop_after) and stop_after > 0):
        raise InputError(f"--stop-after must be a positive number of minutes, got {stop_after}")
    tasks = parse_tasks(plan, runs)
    check_advice(out, tasks)
    prepare(out, plan)
    deadline = None if stop_after is None else time.time() + 60 * stop_after
    train_tasks(out, plan, tasks, workers, deadline=deadline)
    for arm, seed in tasks:
        steps = steps_done(out, plan, (arm, seed))
        typer.echo(f"{arm}-{seed}: {steps:,} of {plan.timesteps:,} steps")


def _run_with_progress(out: Path, plan: Plan, workers: Workers) -> None:
    """:func:`engine.validation.validate.validate` in a thread, with a bar per arm (steps
    logged by its runs) and the time left, polled from the runs' metrics files."""
    from engine.validation.runs import arm_tasks, pilot_tasks
    from engine.validation.validate import steps_done, validate

    tasks = [*pilot_tasks(plan), *arm_tasks(plan)]
    failure: list[BaseException] = []

    def work() -> None:
        try:
            validate(out, plan, workers=workers, command=shlex.join(["acv", *sys.argv[1:]]))
        except BaseException as exc:  # re-raised in the main thread, where the CLI reports it
            failure.append(exc)

    thread = threading.Thread(target=work, daemon=True)
    columns = (TextColumn("{task.description:>10}"), BarColumn(), TimeRemainingColumn())
    with Progress(*columns) as progress:
        bars = {}
        for name in dict.fromkeys(name for name, _ in tasks):
            runs = [t for t in tasks if t[0] == name]
            bars[name] = (progress.add_task(name, total=len(runs) * plan.timesteps), runs)
        thread.start()
        while thread.is_alive():
            for bar, runs in bars.values():
                progress.update(bar, completed=sum(steps_done(out, plan, t) for t in runs))
            thread.join(timeout=2.0)
    if failure:
        raise failure[0]
