"""Options that several ``acv`` commands take, each written once (typer reads the flag and
its help from the ``Annotated`` alias; each command gives its own default)."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from app.core.limits import MAX_DB_ID
from engine.candidates import SAMPLING_MODES
from engine.teachers import TEACHERS

EnvOpt = Annotated[str, typer.Option(help="Gymnasium MuJoCo env id.")]
CandidatesOpt = Annotated[int, typer.Option(help="Number of candidate states (2..128).")]
CoinOpt = Annotated[float, typer.Option(help="Braverman-Mossel coin probability.")]
SamplingOpt = Annotated[
    str, typer.Option(help=f"How candidates are sampled: {' or '.join(SAMPLING_MODES)}.")
]
TeacherOpt = Annotated[str, typer.Option(help=f"Judge: {', '.join(TEACHERS)}.")]
NoiseOpt = Annotated[float, typer.Option(help="Probability of flipping each decision.")]
NEnvsOpt = Annotated[int, typer.Option(help="Parallel envs per run.")]
NumStepsOpt = Annotated[int, typer.Option(help="Steps per env per rollout.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print JSON instead of text.")]


def id_option(help: str) -> Any:
    """A database id's option, 1..:data:`MAX_DB_ID` (the id columns' width): a larger one is
    the usage error (exit 2) on every backend, not SQLite's overflow or PostgreSQL's range."""
    return typer.Option(min=1, max=MAX_DB_ID, help=help)


#: Where an experiment's advice comes from: one of these (app.runs.spec checks which).
AdviceTeacherOpt = Annotated[str | None, typer.Option(help="A simulated teacher's advice.")]
AdviceParticipantOpt = Annotated[int | None, id_option("A finished participant's advice.")]
AdvicePoolOpt = Annotated[
    list[int] | None,
    typer.Option(help="Pooled advice: a finished participant; give it twice or more."),
]
AllParticipantsOpt = Annotated[
    bool, typer.Option("--all-participants", help="Pooled advice: every finished participant.")
]
PoolWeightingOpt = Annotated[
    str | None, typer.Option(help="How a pool is averaged: mean or reliability.")
]
