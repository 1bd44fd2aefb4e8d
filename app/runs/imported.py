"""Policies from elsewhere as runs (issue 44 §2): how an imported policy is stored, and how
its run row and its experiment say what it is.

An imported policy is a ``runs`` row like ACV's own runs, so that the verdict, the experiment
page and the compare page read it as they read any run:

- its ``config`` is ``{"imported": {...}}`` (:data:`IMPORTED`): the arm, the stored files'
  hashes, the policy's sizes and the declared training settings (algorithm, steps, seed and
  the hash of the tree the wrapper used), which ACV did not see happen; a pooled advice's
  weights sit beside it as ``pool_weights``, where :mod:`app.runs.pools` reads them;
- its ``algo`` names the arm as ACV's own would train it: ``ppo-shaped`` (advised: the
  wrapper's ``R + scale (F + offset)``) or ``ppo`` (baseline and pilot); its ``timesteps``
  and ``seed`` are the declared ones;
- it is queued: a worker judges it (:mod:`app.runs.imported_judge`) instead of training it.

An *external* experiment (``spec["external"]``, :mod:`app.runs.external`) holds only such
runs. Only ONNX is ever stored: under ``<runs dir>/policies/`` (:func:`policy_store`), named
by the SHA-256 of the file, with the observation normalisation's ``.npz`` beside it; the
judges' rollouts are cached there too, by the policy's content hash.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from pathlib import Path
from typing import Any, TypeVar

from app.models import Experiment, ExperimentRole, Run
from engine.treefile import TreeDocument, dumps

K = TypeVar("K")
T = TypeVar("T")

#: The key of an imported run's ``config`` that holds what it is.
IMPORTED = "imported"
#: The key of an external experiment's ``spec``.
EXTERNAL = "external"
#: The key of an external experiment's ``spec`` holding its frozen advice (not shown by the API).
FROZEN = "frozen"
#: Arms an imported policy takes part in, by the name the upload gives.
ARMS: dict[str, ExperimentRole] = {role.value: role for role in ExperimentRole}
#: What each arm's run row records as its algo.
ARM_ALGOS: dict[ExperimentRole, str] = {
    ExperimentRole.ADVISED: "ppo-shaped",
    ExperimentRole.BASELINE: "ppo",
    ExperimentRole.PILOT: "ppo",
}
#: The folder of the runs dir where policies, their normalisations and rollouts live.
POLICIES = "policies"
#: Bounds on what is copied from a model's metadata or an SB3 save into the run's config.
MAX_NOTES, MAX_NOTE_KEY, MAX_NOTE_TEXT = 32, 64, 200


def imported_of(run: Run) -> dict[str, Any] | None:
    """What an imported run is (its ``config["imported"]``); None for ACV's own runs."""
    config = run.config if isinstance(run.config, dict) else {}
    found = config.get(IMPORTED)
    return found if isinstance(found, dict) else None


def is_imported(run: Run) -> bool:
    """Whether ``run`` is a policy from elsewhere, judged but never trained by ACV."""
    return imported_of(run) is not None


def is_external(experiment: Experiment) -> bool:
    """Whether the experiment's runs are imported policies."""
    return isinstance(experiment.spec, dict) and experiment.spec.get(EXTERNAL) is True


def public_spec(spec: dict[str, Any]) -> dict[str, Any]:
    """An experiment's spec as the API shows it: without an external one's frozen tree."""
    return {k: v for k, v in spec.items() if k != FROZEN}


def tree_digest(doc: TreeDocument) -> str:
    """SHA-256 (hex) of the tree's ``acv.tree/1`` file as ACV writes it (:func:`dumps`:
    deterministic, so ``sha256sum`` of the file that ``acv agents experiment --tree-out`` or
    ``acv participant tree`` writes gives it): what ``tree_sha256`` declares for the tree a
    policy trained with."""
    return hashlib.sha256(dumps(doc).encode()).hexdigest()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def policy_store(runs_root: Path) -> Path:
    """Where stored policies, normalisations and their judges' rollouts live."""
    return Path(runs_root) / POLICIES


def onnx_file(runs_root: Path, digest: str) -> Path:
    """The stored ONNX file whose SHA-256 is ``digest``."""
    return policy_store(runs_root) / f"{_hex(digest)}.onnx"


def npz_file(runs_root: Path, digest: str) -> Path:
    """The stored normalisation ``.npz`` whose SHA-256 is ``digest``."""
    return policy_store(runs_root) / f"{_hex(digest)}.npz"


def _hex(digest: str) -> str:
    if len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
        raise ValueError(f"not a SHA-256 in hex: {digest!r}")
    return digest


def store_blob(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` (content-addressed: left alone when it exists) through a
    temporary file and a rename, so a reader never sees half a file."""
    if path.is_file():
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_blob(path: Path, digest: str) -> bytes:
    """A stored file's bytes, checked against the hash it is stored under.

    Raises:
        OSError: the file is missing or damaged (its hash differs).
    """
    data = path.read_bytes()
    if sha256(data) != digest:
        raise OSError(f"{path} is damaged: its SHA-256 is not {digest}")
    return data


def notes(values: dict[str, Any]) -> dict[str, str | int | float | bool | None]:
    """At most :data:`MAX_NOTES` plain values of a model's metadata or an SB3 save, keys and
    text cut short, to keep in the run's config and show."""
    kept: dict[str, str | int | float | bool | None] = {}
    for key, value in list(values.items())[:MAX_NOTES]:
        if isinstance(value, str):
            value = value[:MAX_NOTE_TEXT]
        elif isinstance(value, float) and not math.isfinite(value):  # not JSON
            value = None
        elif not isinstance(value, int | float | bool) and value is not None:
            continue
        kept[str(key)[:MAX_NOTE_KEY]] = value
    return kept


def latest_only(
    judged: dict[K, dict[int, dict[int, T]]],
) -> dict[K, dict[int, dict[int, T]]]:
    """Each run's latest judged checkpoint, all placed at one step, the largest of theirs:
    role -> run id -> ``{step: rows}``. An external experiment's runs each have one
    checkpoint, at the steps their trainers declare, which need not be equal."""
    latest = [max(by_step) for by_run in judged.values() for by_step in by_run.values() if by_step]
    if not latest:
        return judged
    step = max(latest)
    return {
        role: {rid: {step: t[max(t)]} for rid, t in by_run.items() if t}
        for role, by_run in judged.items()
    }
