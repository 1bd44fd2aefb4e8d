"""``acv experiment``: advised runs on k seeds with a matched no-advice baseline, and the
verdict (the same service layer as ``/api/experiments``). Runs train on the worker
(``acv serve`` or ``acv worker``), as every queued run does."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer
from pydantic import ValidationError

from app.cli.options import (
    AdviceParticipantOpt,
    AdvicePoolOpt,
    AdviceTeacherOpt,
    AllParticipantsOpt,
    JsonOpt,
    NEnvsOpt,
    PoolWeightingOpt,
    id_option,
)
from app.cli.root import cli, fail, validation_errors
from app.cli.serve import cli_runtime
from app.core.limits import MAX_DB_ID
from app.models import RunStatus
from app.runs import experiments, verdicts
from app.runs.experiments import DEFAULT_PILOT_SEEDS, DEFAULT_SEEDS, ExperimentSpec
from app.runs.imported import is_external
from app.runs.schemas import ExperimentCreate
from engine.judges import DEFAULT_JUDGE

Opt = typer.Option
experiment_cli = typer.Typer(help="Experiments: k seeds with a matched baseline.")
cli.add_typer(experiment_cli, name="experiment", no_args_is_help=True)


@experiment_cli.command("create")
def create(
    study: Annotated[int, id_option("The study whose bracket the advice is over.")],
    timesteps: Annotated[int, Opt(help="Env steps per run.")],
    teacher: AdviceTeacherOpt = None,
    participant: AdviceParticipantOpt = None,
    pool: AdvicePoolOpt = None,
    all_participants: AllParticipantsOpt = False,
    pool_weighting: PoolWeightingOpt = None,
    algo: Annotated[str, Opt(help="How the advised runs train.")] = "bipars-em",
    seeds: Annotated[int, Opt(help="Evaluation seeds per arm (2..20).")] = DEFAULT_SEEDS,
    pilot_seeds: Annotated[int, Opt(help="Pilot runs (1..10).")] = DEFAULT_PILOT_SEEDS,
    first_seed: Annotated[int, Opt(help="The first evaluation seed.")] = 0,
    n_envs: NEnvsOpt = 4,
    advice_scale: Annotated[float | None, Opt(help="Multiplies F (advised runs).")] = None,
    checkpoint_every: Annotated[int | None, Opt(help="Env steps between checkpoints.")] = None,
    num_steps: Annotated[int | None, Opt(help="Steps per env per rollout.")] = None,
) -> None:
    """Queue the advised, baseline and pilot runs (baseline and pilot runs already trained
    with the same settings are reused); prints the experiment's id and its runs."""
    run: dict[str, Any] = {"study_id": study, "algo": algo, "timesteps": timesteps}
    run |= {"n_envs": n_envs, "teacher": teacher, "participant_id": participant}
    run |= {"participant_ids": pool, "all_participants": all_participants or None}
    run |= {"pool_weighting": pool_weighting}
    run |= {"advice_scale": advice_scale, "checkpoint_every": checkpoint_every}
    run |= {"num_steps": num_steps, "seed": first_seed}
    run |= {"seeds": seeds, "pilot_seeds": pilot_seeds}
    spec = _experiment_spec(run)
    with cli_runtime() as runtime, runtime.sessions() as session:
        experiment = experiments.create_experiment(session, spec=spec)
        members = experiments.members(session, experiment_id=experiment.id)
    typer.echo(f"experiment {experiment.id} queued: {len(members)} runs")
    for role, member in members:
        typer.echo(f"{member.id}\t{role}\t{member.algo}\tseed {member.seed}\t{member.status}")


def _experiment_spec(body: dict[str, Any]) -> ExperimentSpec:
    """The experiment ``body`` asks for, checked as the API checks its body
    (:class:`ExperimentCreate`: the same bounds, from the command line too)."""
    try:
        given = {name: value for name, value in body.items() if value is not None}
        return ExperimentCreate.model_validate(given).experiment_spec()
    except ValidationError as exc:
        fail(validation_errors(exc))


@experiment_cli.command("list")
def list_(study: Annotated[int | None, id_option("Only this study's.")] = None) -> None:
    """One line per experiment: id, study, algo (``external``: imported policies), seeds, runs
    succeeded."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        for experiment in experiments.list_experiments(session, study_id=study):
            members = experiments.members(session, experiment_id=experiment.id)
            done = sum(run.status == RunStatus.SUCCEEDED for _, run in members)
            algo = "external" if is_external(experiment) else experiment.spec.get("algo")
            typer.echo(
                f"{experiment.id}\tstudy {experiment.study_id}\t{algo}\t"
                f"{len(experiment.seeds)} seeds\t{done}/{len(members)} runs succeeded"
            )


@experiment_cli.command("verdict")
def verdict(
    experiment: Annotated[int, typer.Argument(min=1, max=MAX_DB_ID, help="The experiment's id.")],
    judge: Annotated[str, Opt(help="How the runs score states.")] = DEFAULT_JUDGE,
    step: Annotated[int | None, Opt(help="Checkpoint (default: latest judged).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The verdict: advised runs against the matched baseline, on the matches that can tell."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        found = verdicts.experiment_verdict(
            session, experiment_id=experiment, judge=judge, step=step
        )
    if found is None:
        fail(f"experiment {experiment} has too few judged runs for a verdict yet")
    if as_json:
        body = {"judge": found.judge, "step": found.step, "runs": found.runs}
        body |= {"final": found.final, "diagnostic": found.diagnostic}
        typer.echo(json.dumps(body | {"verdict": found.verdict.to_json()}, indent=1))
    else:
        look = "" if found.decides else "diagnostic, " if found.diagnostic else "interim, "
        typer.echo(f"step {found.step} ({look}judge {found.judge}): {found.verdict.text}")
