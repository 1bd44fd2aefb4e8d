"""``acv validate-round2``: validation round 2, as declared in docs/validation.md §6 before its
runs (issue 40). Resumable: a second call goes on where the first stopped; ``--runs`` trains
named runs only (for a while with ``--stop-after``), to share the round between machines."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from app.cli.root import cli
from app.cli.serve import service_errors
from engine.errors import InputError
from engine.validation.workers import Workers

if TYPE_CHECKING:
    from engine.validation.round2_runs import Round2Plan

Opt = typer.Option
#: Round 1's `standing` bracket, which round 2's standing-shuffled arm is judged on.
STANDING = Path(__file__).parents[2] / "docs/validation/humanoid-standing/brackets/bracket_0.json"


@cli.command("validate-round2")
def validate_round2(
    out: Annotated[Path, Opt(help="Round 2 folder (outside the repository).")],
    env: Annotated[str, Opt(help="Humanoid-v5 or Hopper-v5 (§6.3).")] = "Humanoid-v5",
    jobs: Annotated[int, Opt(help="Runs trained at once (one core each).")] = 1,
    ray_address: Annotated[
        str | None, Opt(envvar="ACV_RAY_ADDRESS", help="Train each run as a Ray task there.")
    ] = None,
    runs: Annotated[
        str | None, Opt(help="Train only these runs (label-seed, comma-separated); no measures.")
    ] = None,
    stop_after: Annotated[
        float | None, Opt(help="With --runs: stop each run at a checkpoint after these minutes.")
    ] = None,
    timesteps: Annotated[
        int | None, Opt(help="Env steps per run: the declared budget unless a smoke test.")
    ] = None,
    standing_bracket: Annotated[
        Path, Opt(help="Humanoid-v5: round 1's standing bracket (the reported standing arm).")
    ] = STANDING,
) -> None:
    """Train and measure round 2's runs on one env (pilots, brackets, every arm)."""
    from engine.validation.round2 import DESIGNS
    from engine.validation.round2_runs import Round2Plan

    with service_errors():
        if env not in DESIGNS:
            raise InputError(f"round 2 is declared for {' and '.join(DESIGNS)}, not {env!r}")
        if jobs < 1 or (timesteps is not None and timesteps < 1):
            raise InputError("--jobs and --timesteps must be at least 1")
        humanoid = env == "Humanoid-v5"
        if humanoid and not standing_bracket.is_file():
            raise InputError(f"--standing-bracket: no file at {standing_bracket}")
        plan = Round2Plan(
            env_id=env,
            timesteps=timesteps or DESIGNS[env][1],
            standing_bracket=str(standing_bracket.resolve()) if humanoid else None,
        )
        workers = Workers(jobs, ray_address or None)
        if runs is None and stop_after is None:
            from engine.validation.round2_measure import run_round

            done = run_round(out, plan, workers)
            typer.echo(f"{len(done)} runs measured; wrote {out / 'summary.json'} and report.md")
            return
        _train_only(out, plan, workers, runs, stop_after)


def _train_only(
    out: Path, plan: Round2Plan, workers: Workers, runs: str | None, stop_after: float | None
) -> None:
    """Train the named runs (to the end, or for ``stop_after`` minutes); measuring is left to
    a call without ``--runs``. Advised runs need the pilots' advice made first."""
    from engine.validation.design import AdviceKind
    from engine.validation.round2_runs import advice_file, arm_of, prepare, tasks, train_all

    if runs is None:
        raise InputError("--stop-after needs --runs: the runs to train for that long")
    if stop_after is not None and not (math.isfinite(stop_after) and stop_after > 0):
        raise InputError(f"--stop-after must be a positive number of minutes, got {stop_after}")
    known = {f"{label}-{seed}": (label, seed) for label, seed in tasks(plan)}
    wanted = [name.strip() for name in runs.split(",") if name.strip()]
    unknown = [name for name in wanted if name not in known]
    if unknown or not wanted:
        raise InputError(f"--runs: {', '.join(unknown) or 'none given'} is not a run of round 2")
    for name in wanted:
        arm, bracket = arm_of(known[name][0])
        if arm.advice is not AdviceKind.NONE and not advice_file(out, arm, bracket).is_file():
            raise InputError(f"{name} trains on advice not made yet: train the pilots first")
    prepare(out, plan)
    deadline = None if stop_after is None else time.time() + 60 * stop_after
    train_all(out, plan, [known[name] for name in wanted], workers, deadline)
    typer.echo(f"trained {', '.join(wanted)}")
