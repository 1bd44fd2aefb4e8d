"""Importing a policy trained elsewhere into an external experiment (issue 44 §2).

The one path of ``POST /api/experiments/{id}/agents`` and ``acv agents import``: the ONNX
model passes :func:`engine.policies.onnx_check.check_onnx` for the experiment's env (env id
from the model's metadata or given with the upload, sizes, operators, weights), its optional
observation normalisation is read as plain arrays, the declared training settings are checked,
and only then are the files stored (content-addressed, :mod:`app.runs.imported`) and the run
queued, to be judged by a worker (:mod:`app.runs.imported_judge`). Every refusal names its rule
and stores nothing. An SB3 ``.zip`` never gets here: the CLI converts it to ONNX first, and
the API refuses it (415).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError, ServiceError
from app.db import writing
from app.models import Experiment, ExperimentRole, ExperimentRun, Run, RunStatus
from app.runs import imported
from app.runs.declared import Declared, checked_declared
from app.runs.experiments import MAX_PILOT_SEEDS, get_experiment, members
from app.runs.external import ExternalInfo, external_info
from engine.errors import InputError
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import CheckedOnnx, check_onnx

#: How every zip file starts (an SB3 save is one; so is an ``.npz``).
ZIP_MAGIC = b"PK\x03\x04"


class UnsupportedFormat(ServiceError):
    """A file the API does not take (an SB3 zip: the CLI converts it)."""

    status_code = 415


@dataclass(frozen=True)
class AgentUpload:
    """One policy to import.

    Attributes:
        onnx: the ONNX file's bytes (the only form stored).
        arm: ``advised``, ``baseline`` or ``pilot``.
        declared: the declared training settings.
        env_id: the env id given with the upload (for a model without one in its metadata).
        obs_norm: the observation normalisation's ``.npz`` bytes, if any.
        uploaded_as: ``onnx``, or ``sb3-zip`` when the CLI converted an SB3 save.
        sb3: an SB3 save's plain JSON fields (what its trainer says), else empty.
    """

    onnx: bytes = field(repr=False)
    arm: str
    declared: Declared = Declared()
    env_id: str | None = None
    obs_norm: bytes | None = field(default=None, repr=False)
    uploaded_as: str = "onnx"
    sb3: Mapping[str, Any] = field(default_factory=dict)


def import_agent(
    session: Session, *, experiment_id: int, upload: AgentUpload, runs_root: Path
) -> Run:
    """Check, store and queue an imported policy of an external experiment.

    Raises:
        NotFoundError: no such experiment.
        ConflictError: an experiment that trains its own runs, an arm already full, a seed
            already imported in this arm, or the same files imported already.
        UnsupportedFormat: a zip (an SB3 save) instead of ONNX.
        InputError: any rule of the model, the normalisation or the declared settings.
    """
    experiment = get_experiment(session, experiment_id=experiment_id)
    if not imported.is_external(experiment):
        raise ConflictError(
            f"experiment {experiment_id} trains its own runs: policies are imported into an "
            "external experiment (POST /api/experiments/external, acv agents experiment)"
        )
    info = external_info(experiment)
    role = _arm(upload.arm)
    if upload.onnx[:4] == ZIP_MAGIC:
        raise UnsupportedFormat(
            "the file is a zip (an SB3 save?), not an ONNX model: the API stores ONNX only; "
            "`acv agents import` converts an SB3 MlpPolicy zip to ONNX without unpickling it"
        )
    model = check_onnx(
        upload.onnx,
        env_id=info.env_id,
        obs_dim=info.obs_dim,
        act_dim=info.act_dim,
        declared_env_id=upload.env_id or None,
    )
    norm = (
        None
        if upload.obs_norm is None
        else ObsNormalisation.from_npz(upload.obs_norm, obs_dim=info.obs_dim)
    )
    declared = checked_declared(upload.declared, model.metadata, role)
    config = _config(upload, model, norm is not None, declared, role, info)
    _check_place(session, experiment, info, role, config)  # early, before files are written
    for path, data in _files(runs_root, upload, config):
        imported.store_blob(path, data)  # content-addressed: kept when already there
    # Never removed, even when _store refuses the run: another request may be storing a run
    # that names the same file. A refused upload's file stays, reused by the same bytes.
    return _store(session, experiment, info, role, config)


def _arm(arm: str) -> ExperimentRole:
    if arm not in imported.ARMS:
        raise InputError(f"unknown arm {arm!r}: expected one of {', '.join(imported.ARMS)}")
    return imported.ARMS[arm]


def _config(
    upload: AgentUpload,
    model: CheckedOnnx,
    normalised: bool,
    declared: Declared,
    role: ExperimentRole,
    info: ExternalInfo,
) -> dict[str, Any]:
    """The run's ``config["imported"]``."""
    return {
        "arm": role.value,
        "uploaded_as": upload.uploaded_as,
        "onnx_sha256": model.digest,
        "onnx_bytes": len(model.data),
        "obs_norm_sha256": imported.sha256(upload.obs_norm)
        if normalised and upload.obs_norm is not None
        else None,
        "env_id": model.env_id,
        "obs_dim": model.obs_dim,
        "act_dim": model.act_dim,
        "opset": model.opset,
        "declared": {
            "algorithm": declared.algorithm,
            "steps": declared.steps,
            "seed": declared.seed,
            "tree_sha256": declared.tree_sha256,
        },
        "tree_matches": None
        if declared.tree_sha256 is None
        else declared.tree_sha256 == info.tree_sha256,
        "metadata": imported.notes(dict(model.metadata)),
        "sb3": imported.notes(dict(upload.sb3)) or None,
        "imported_at": datetime.now(UTC).isoformat(timespec="seconds"),
    }


def _files(
    runs_root: Path, upload: AgentUpload, config: dict[str, Any]
) -> list[tuple[Path, bytes]]:
    files = [(imported.onnx_file(runs_root, config["onnx_sha256"]), upload.onnx)]
    if config["obs_norm_sha256"] is not None and upload.obs_norm is not None:
        files.append((imported.npz_file(runs_root, config["obs_norm_sha256"]), upload.obs_norm))
    return files


def _check_place(
    session: Session,
    experiment: Experiment,
    info: ExternalInfo,
    role: ExperimentRole,
    config: dict[str, Any],
) -> None:
    """Refuse a policy that has no place in the experiment: its arm is full, its seed taken
    in that arm, a pilot on an evaluation seed (or the reverse), or the same files twice."""
    seed = config["declared"]["seed"]
    arms: dict[ExperimentRole, list[int]] = {r: [] for r in ExperimentRole}
    for member_role, run in members(session, experiment_id=experiment.id):
        arms[member_role].append(run.seed)
        other = imported.imported_of(run) or {}
        files = (other.get("onnx_sha256"), other.get("obs_norm_sha256"))
        if files == (config["onnx_sha256"], config["obs_norm_sha256"]):
            raise ConflictError(
                f"this policy (ONNX sha256 {config['onnx_sha256'][:12]}…, with the same "
                f"normalisation) is run {run.id} of experiment {experiment.id} already"
            )
    most = MAX_PILOT_SEEDS if role == ExperimentRole.PILOT else info.seeds_per_arm
    if len(arms[role]) >= most:
        raise ConflictError(
            f"the {role.value} arm of experiment {experiment.id} is full: it takes {most} policies"
        )
    if seed in arms[role]:
        raise ConflictError(
            f"experiment {experiment.id} has a {role.value} policy of seed {seed} already"
        )
    evaluation = set(arms[ExperimentRole.ADVISED]) | set(arms[ExperimentRole.BASELINE])
    if role == ExperimentRole.PILOT and seed in evaluation:
        raise InputError(
            f"seed {seed} is an evaluation seed of experiment {experiment.id}: pilot policies "
            "use seeds of their own, or they would pick the matches on seeds they are judged on"
        )
    if role != ExperimentRole.PILOT and seed in arms[ExperimentRole.PILOT]:
        raise InputError(
            f"seed {seed} is a pilot seed of experiment {experiment.id}: evaluation policies use "
            "other seeds"
        )


def _store(
    session: Session,
    experiment: Experiment,
    info: ExternalInfo,
    role: ExperimentRole,
    config: dict[str, Any],
) -> Run:
    """The run and its place in the experiment, in one write transaction that holds the
    experiment's row (PostgreSQL; SQLite has one writer) while it checks the place again."""
    declared = config["declared"]
    run = Run(
        study_id=experiment.study_id,
        participant_id=info.participant_id,
        teacher=info.teacher,
        advice_pool=info.advice_pool,
        algo=imported.ARM_ALGOS[role],
        timesteps=declared["steps"],
        seed=declared["seed"],
        n_envs=1,
        config={imported.IMPORTED: config}
        | ({} if info.pool_weights is None else {"pool_weights": info.pool_weights}),
        advice=info.tree,
        status=RunStatus.QUEUED,
        resume=False,
        cancel_requested=False,
        progress=0,
    )
    with writing(session):
        locked = select(Experiment).where(Experiment.id == experiment.id).with_for_update()
        held = session.scalars(locked).one()
        _check_place(session, held, info, role, config)
        session.add(run)
        session.flush()
        session.add(ExperimentRun(experiment_id=held.id, run_id=run.id, role=role))
        session.flush()
        _record_seeds(session, held)
    return run


def _record_seeds(session: Session, experiment: Experiment) -> None:
    """The experiment's ``seeds`` (advised and baseline) and ``pilot_seeds``, as imported."""
    by_role: dict[ExperimentRole, set[int]] = {r: set() for r in ExperimentRole}
    for role, run in members(session, experiment_id=experiment.id):
        by_role[role].add(int(run.seed))
    experiment.seeds = sorted(by_role[ExperimentRole.ADVISED] | by_role[ExperimentRole.BASELINE])
    experiment.pilot_seeds = sorted(by_role[ExperimentRole.PILOT])
