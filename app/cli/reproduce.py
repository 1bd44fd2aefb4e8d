"""``acv reproduce``: the paper's experiments, end to end, resumable."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from app.cli.options import CandidatesOpt, CoinOpt, EnvOpt, NEnvsOpt, NumStepsOpt, id_option
from app.cli.root import cli
from app.reproduce.plan import ReproduceConfig
from engine.envs import DEFAULT_ENV_ID, check_env_id
from engine.errors import InputError
from engine.treefile import TreeDocument

Opt = typer.Option


@cli.command()
def reproduce(
    out: Annotated[
        Path, Opt(help="Results folder (a second call with the same settings resumes).")
    ] = Path("results"),
    timesteps: Annotated[int, Opt(help="Env steps per agent and seed.")] = 1_000_000,
    seeds: Annotated[
        int,
        Opt(help="Training seeds of the core arms (ppo, both Case 1 (paper), Case 2, control)."),
    ] = 1,
    extra_seeds: Annotated[
        int, Opt(help="Training seeds of the other arms (Case 1 tree, MGL, ablations).")
    ] = 1,
    env: EnvOpt = DEFAULT_ENV_ID,
    n_envs: NEnvsOpt = 4,
    num_steps: NumStepsOpt = 512,
    checkpoint_every: Annotated[int, Opt(help="Checkpoint period in env steps.")] = 50_000,
    candidates: CandidatesOpt = 16,
    p: CoinOpt = 0.9,
    bracket_seed: Annotated[int, Opt(help="Seed of the candidates and the bracket.")] = 0,
    study: Annotated[
        int | None, id_option("Use a real participant's tree from this study as the Case 2 advice.")
    ] = None,
    participant: Annotated[int | None, id_option("That participant's id.")] = None,
    jobs: Annotated[int, Opt(min=1, help="Training runs at a time (one core each).")] = 1,
) -> None:
    """Train ppo, Case 1, Case 2 and the naive-shaping control on one bracket; write the
    learning curves, both cases' trees side by side, summary.json and README.md."""
    from app.cli.serve import service_errors

    with service_errors():
        check_env_id(env)
        config = ReproduceConfig(
            env_id=env,
            timesteps=timesteps,
            seeds=seeds,
            extra_seeds=extra_seeds,
            n_envs=n_envs,
            num_steps=num_steps,
            checkpoint_every=checkpoint_every,
            candidates=candidates,
            p=p,
            bracket_seed=bracket_seed,
            study_id=study,
            participant_id=participant,
        )
        _reproduce(out, config, jobs)
    typer.echo(f"wrote {out / 'README.md'} and {out / 'summary.json'}")


def _reproduce(out: Path, config: ReproduceConfig, jobs: int) -> None:
    """Prepare the bracket and advice, train every arm, then write the report."""
    from app.reproduce.plan import prepare, train_all
    from app.reproduce.report import write_report

    trees = prepare(out, config, participant_advice(config))
    train_all(out, config, trees, jobs=jobs)
    typer.echo("training done; extracting agent trees and drawing figures")
    write_report(out, config, trees, command=shlex.join(["acv", *sys.argv[1:]]), jobs=jobs)


def participant_advice(config: ReproduceConfig) -> TreeDocument | None:
    """The participant's Human Preference Tree from the database, when one is named."""
    if config.participant_id is None:
        return None
    from app.cli.serve import cli_runtime
    from app.core.errors import NotFoundError
    from app.labelling.trees import participant_tree
    from app.models import Participant

    with cli_runtime() as runtime, runtime.sessions() as session:
        doc = participant_tree(session, participant_id=config.participant_id)
        if session.get_one(Participant, config.participant_id).study_id != config.study_id:
            raise NotFoundError(
                f"participant {config.participant_id} is not in study {config.study_id}"
            )
    if doc.env_id != config.env_id:
        raise InputError(f"study {config.study_id} is on {doc.env_id}; pass --env {doc.env_id}")
    return doc
