"""``acv study create|list``, ``acv participant add`` and ``acv simulate``: the service layer
from the command line, on the database the settings name (migrated first)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from app.cli.options import (
    CandidatesOpt,
    CoinOpt,
    EnvOpt,
    NoiseOpt,
    SamplingOpt,
    TeacherOpt,
    id_option,
)
from app.cli.root import cli, fail
from app.cli.serve import cli_runtime
from app.labelling import participants, trees
from app.labelling import simulate as labelling_simulate
from app.labelling.participants import invite_url
from app.models import StudyStatus
from app.studies import service as studies
from app.studies.clips import CLIPS_WARNING, clips_state
from engine.disagreement import MAX_PAIRS
from engine.envs import DEFAULT_ENV_ID
from engine.practice import MAX_PRACTICE_PAIRS, MIN_PRACTICE_PAIRS
from engine.treefile import dump_tree

study_cli = typer.Typer(help="Create and list studies.", no_args_is_help=True)
participant_cli = typer.Typer(help="Invite participants.", no_args_is_help=True)
cli.add_typer(study_cli, name="study")
cli.add_typer(participant_cli, name="participant")


@study_cli.command("create")
def create(
    name: Annotated[str, typer.Option(help="Shown to the researcher.")],
    env: EnvOpt = DEFAULT_ENV_ID,
    candidates: CandidatesOpt = 16,
    p: CoinOpt = 0.9,
    seed: Annotated[int, typer.Option(help="Seed for sampling and seeding.")] = 0,
    sampling: SamplingOpt = "uniform",
    disagreement_pairs: Annotated[
        int,
        typer.Option(
            help=f"Extra pairs asked after the bracket where the advice and a no-advice ppo "
            f"run disagree (0..{MAX_PAIRS}; > 0 needs such a run on the env)."
        ),
    ] = 0,
    instructions: Annotated[str, typer.Option(help="Text shown to participants.")] = "",
    instructions_file: Annotated[
        Path | None, typer.Option(help="Read the instructions from this file instead.")
    ] = None,
    allow_ties: Annotated[
        bool,
        typer.Option(
            help='Participants may answer "can\'t tell" (the bracket advances by a seeded coin).'
        ),
    ] = False,
    practice_pairs: Annotated[
        int,
        typer.Option(
            help=f"Practice pairs before the bracket: 0 (none) or {MIN_PRACTICE_PAIRS} to "
            f"{MAX_PRACTICE_PAIRS}, on states that are not candidates; never stored."
        ),
    ] = 0,
    clips: Annotated[
        bool,
        typer.Option(
            help="Show participants 2 s motion clips of the candidates, rendered after the "
            "stills (" + CLIPS_WARNING + ")"
        ),
    ] = False,
) -> None:
    """Create a study, then sample and render its candidates (waits until ready, and with
    --clips until its clips are rendered)."""
    text = instructions_file.read_text(encoding="utf-8") if instructions_file else instructions
    with cli_runtime() as runtime:
        with runtime.sessions() as session:
            spec = studies.StudySpec(
                name=name,
                env_id=env,
                n_candidates=candidates,
                p=p,
                seed=seed,
                sampling=sampling,
                instructions=text,
                disagreement_pairs=disagreement_pairs,
                allow_ties=allow_ties,
                practice_pairs=practice_pairs,
                clips=clips,
            )
            study = studies.create_study(session, spec=spec)
        runtime.prepare(study.id)
        with runtime.sessions() as session:
            study = studies.get_study(session, study_id=study.id)
    if study.status != StudyStatus.READY:
        fail(f"study {study.id} could not be prepared: {study.error}")
    typer.echo(f"study {study.id} ready: {study.n_candidates} {study.env_id} candidates")
    if clips:
        typer.echo(f"clips {clips_state(study)}" + (f": {study.error}" if study.error else ""))


@study_cli.command("list")
def list_() -> None:
    """One line per study: id, status, env, candidates, participants finished, name."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        for study in studies.list_studies(session):
            people = participants.list_participants(session, study_id=study.id)
            done = sum(s.progress.finished for s in people)
            typer.echo(
                f"{study.id}\t{study.status}\t{study.env_id}\t{study.n_candidates}\t"
                f"{done}/{len(people)} finished\t{study.name}"
            )


@participant_cli.command("add")
def add(
    study: Annotated[int, id_option("Study id.")],
    count: Annotated[int, typer.Option(help="How many participants to invite.")] = 1,
    name: Annotated[str | None, typer.Option(help="Optional note on the invites.")] = None,
) -> None:
    """Invite participants; prints one invite link per line."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        people = participants.add_participants(session, study_id=study, count=count, name=name)
        base = runtime.settings.public_url or "http://127.0.0.1:8000"
        for person in people:
            typer.echo(invite_url(base, person.token))


@participant_cli.command("tree")
def tree(
    participant: Annotated[int, id_option("Participant id.")],
    out: Annotated[Path, typer.Option(help="Where to write the tree (acv.tree/1).")],
) -> None:
    """Write a finished participant's Human Preference Tree (the input of `acv train`)."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        doc = trees.participant_tree(session, participant_id=participant)
    dump_tree(doc, out)
    typer.echo(f"wrote {out}: {len(doc.candidates)} candidates, champion {doc.tree.root}")


@cli.command()
def simulate(
    study: Annotated[int, id_option("Study id.")],
    teacher: TeacherOpt = "standing",
    participants_: Annotated[
        int, typer.Option("--participants", help="How many simulated participants.")
    ] = 1,
    noise: NoiseOpt = 0.0,
    seed: Annotated[int, typer.Option(help="Seed of the teacher's noise.")] = 0,
) -> None:
    """Simulated participants label the study's bracket through the service layer."""
    with cli_runtime() as runtime, runtime.sessions() as session:
        people = labelling_simulate.simulate(
            session,
            study_id=study,
            teacher=teacher,
            participants=participants_,
            noise=noise,
            seed=seed,
        )
        for person in people:
            typer.echo(f"participant {person.id} finished ({teacher})")
