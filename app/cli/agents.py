"""``acv agents``: policies trained elsewhere, judged by ACV (issue 44 §2); the same services
as ``POST /api/experiments/external`` and ``POST /api/experiments/{id}/agents``.

``acv agents experiment`` creates an external experiment (and can write its advice tree, which
the advised policies train with); ``acv agents import`` imports one policy into it: an ONNX
file, or a Stable-Baselines3 ``MlpPolicy`` ``.zip``, which is read without unpickling
(:mod:`engine.policies.sb3`, the activation named by ``--activation``) and converted to ONNX,
the only form stored. Files are size-capped before they are read; bad input is one line on
stderr and exit code 2, and stores nothing. A worker (``acv serve`` or ``acv worker``) then
judges the policy, as it trains a queued run.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from app.cli.options import (
    AdviceParticipantOpt,
    AdvicePoolOpt,
    AdviceTeacherOpt,
    AllParticipantsOpt,
    PoolWeightingOpt,
    id_option,
)
from app.cli.root import cli, fail
from app.cli.serve import cli_runtime
from app.jobs.settings import JobSettings
from app.runs.agent_import import ZIP_MAGIC, AgentUpload, import_agent
from app.runs.declared import Declared
from app.runs.experiments import DEFAULT_SEEDS
from app.runs.external import ExternalSpec, create_external_experiment, external_experiment
from app.runs.spec import advice_source
from engine.policies.normalisation import MAX_NPZ_BYTES
from engine.policies.onnx_check import OnnxLimits
from engine.treefile import dump_tree, tree_from_json

Opt = typer.Option
agents_cli = typer.Typer(help="Policies trained elsewhere: external experiments and imports.")
cli.add_typer(agents_cli, name="agents", no_args_is_help=True)
#: What an SB3 save may weigh (:class:`engine.policies.sb3.Sb3Limits`, not imported: torch).
MAX_ZIP_BYTES = 256 * 1024 * 1024
ACTIVATIONS = ("tanh", "relu")


@agents_cli.command("experiment")
def experiment(
    study: Annotated[int, id_option("The study whose bracket the advice is over.")],
    teacher: AdviceTeacherOpt = None,
    participant: AdviceParticipantOpt = None,
    pool: AdvicePoolOpt = None,
    all_participants: AllParticipantsOpt = False,
    pool_weighting: PoolWeightingOpt = None,
    seeds: Annotated[int, Opt(help="The most policies per arm, advised and baseline (2..20).")] = (
        DEFAULT_SEEDS
    ),
    tree_out: Annotated[
        Path | None, Opt(help="Write the advice tree here (what the advised policies train on).")
    ] = None,
) -> None:
    """Create an external experiment: its runs are policies you import (advised, baseline and
    pilot); prints its id and the SHA-256 of its advice tree, which advised policies declare."""
    fields = {"teacher": teacher, "participant_id": participant, "participant_ids": pool}
    fields |= {"all_participants": all_participants or None, "pool_weighting": pool_weighting}
    spec = ExternalSpec(study_id=study, advice=advice_source(fields), seeds_per_arm=seeds)
    if tree_out is not None:  # checked first: a refusal must store no experiment
        _check_writable(tree_out, "--tree-out")
    with cli_runtime() as runtime, runtime.sessions() as session:
        created = create_external_experiment(session, spec=spec)
        info = external_experiment(session, experiment_id=created.id)
    if tree_out is not None:
        dump_tree(tree_from_json(info.tree), tree_out)
    typer.echo(f"external experiment {created.id} on {info.env_id}: up to {seeds} seeds per arm")
    typer.echo(f"tree_sha256 {info.tree_sha256}")


def _check_writable(path: Path, flag: str) -> None:
    """Exit 2 unless a file can be written at ``path`` (its folder exists and is writable, and
    it is not itself a folder)."""
    folder = path.parent
    if path.is_dir() or not folder.is_dir() or not os.access(folder, os.W_OK):
        fail(f"{flag} {path}: cannot write a file there (no such folder, or not writable)")


@agents_cli.command("import")
def import_(
    policy: Annotated[Path, typer.Argument(help="An ONNX file, or an SB3 MlpPolicy .zip.")],
    experiment: Annotated[int, id_option("The external experiment.")],
    arm: Annotated[str, Opt(help="advised, baseline or pilot.")],
    seed: Annotated[int | None, Opt(help="Declared seed (else the file's).")] = None,
    steps: Annotated[int | None, Opt(help="Declared env steps (else the file's).")] = None,
    algorithm: Annotated[str | None, Opt(help="Declared algorithm (else the file's).")] = None,
    tree_sha256: Annotated[str | None, Opt(help="The advice tree's hash (advised only).")] = None,
    env_id: Annotated[str | None, Opt(help="The env, for a file that does not name it.")] = None,
    obs_norm: Annotated[
        Path | None, Opt(help="Observation normalisation: .npz of mean, var, clip, epsilon.")
    ] = None,
    activation: Annotated[
        str | None, Opt(help="An SB3 zip's activation_fn: tanh (SB3's default) or relu.")
    ] = None,
) -> None:
    """Import a policy trained elsewhere into an external experiment; a worker judges it."""
    is_zip = _head(policy) == ZIP_MAGIC
    data = _read(policy, MAX_ZIP_BYTES if is_zip else OnnxLimits().max_bytes)
    norm = None if obs_norm is None else _read(obs_norm, MAX_NPZ_BYTES)
    if activation is not None and not is_zip:
        fail("--activation is for an SB3 zip; an ONNX model computes its own")
    if activation is not None and activation not in ACTIVATIONS:
        fail(f"unknown activation {activation!r}: expected {' or '.join(ACTIVATIONS)}")
    with cli_runtime() as runtime, runtime.sessions() as session:
        info = external_experiment(session, experiment_id=experiment)
        upload = AgentUpload(
            onnx=data,
            arm=arm,
            declared=Declared(algorithm, steps, seed, tree_sha256),
            env_id=env_id,
            obs_norm=norm,
        )
        if is_zip:
            upload = _converted(upload, env_id or info.env_id, activation or "tanh")
        runs_root = JobSettings().runs_root(runtime.settings)
        run = import_agent(session, experiment_id=experiment, upload=upload, runs_root=runs_root)
        typer.echo(
            f"run {run.id}: {arm} seed {run.seed} imported into experiment {experiment} "
            f"({run.config['imported']['uploaded_as']}, ONNX sha256 "
            f"{run.config['imported']['onnx_sha256']}); queued to be judged"
        )


def _converted(upload: AgentUpload, env_id: str, activation: str) -> AgentUpload:
    """An SB3 save's upload as ONNX, its plain settings filling the declared seed and steps."""
    from engine.policies.sb3 import sb3_to_onnx  # torch, for weights_only loading

    converted = sb3_to_onnx(upload.onnx, env_id=env_id, activation=activation)
    given, found = upload.declared, converted.declared
    declared = Declared(
        given.algorithm,
        _given_or_found(given.steps, found.get("num_timesteps")),
        _given_or_found(given.seed, found.get("seed")),
        given.tree_sha256,
    )
    return AgentUpload(
        onnx=converted.model.data,
        arm=upload.arm,
        declared=declared,
        env_id=upload.env_id,
        obs_norm=upload.obs_norm,
        uploaded_as="sb3-zip",
        sb3=converted.declared,
    )


def _given_or_found(given: int | None, found: object) -> int | None:
    """The option's value, else the save's when it is a whole number (JSON null: none)."""
    if given is not None or not isinstance(found, int) or isinstance(found, bool):
        return given
    return found


def _head(path: Path) -> bytes:
    with path.open("rb") as f:
        return f.read(4)


def _read(path: Path, cap: int) -> bytes:
    """The file's bytes, refused by its size before it is read."""
    size = path.stat().st_size
    if size > cap:
        fail(f"{path} is {size} bytes, over the limit of {cap} bytes")
    return path.read_bytes()
