"""The training settings an imported policy declares (issue 44 §2): algorithm, steps, seed and
the hash of the tree its advice wrapper used. ACV did not see the policy train: these are the
trainer's word, stored and shown as such, and checked only for form. Each comes with the upload
or, where the upload leaves it out, from the model's ``metadata_props`` (where ACV's own export,
:mod:`engine.policies.export`, and the CLI's SB3 conversion put them).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from app.models import ExperimentRole
from engine.errors import InputError

#: The largest declared training budget and seed, and the longest algorithm's name.
MAX_STEPS, MAX_SEED, MAX_ALGORITHM = 10**12, 2**31 - 1, 100
#: The ``metadata_props`` keys of the declared settings: :mod:`engine.policies.export`'s three
#: (not imported: it loads torch, which the web tier never does), and the tree's hash.
ALGORITHM_KEY, TIMESTEPS_KEY, SEED_KEY, TREE_KEY = "algorithm", "timesteps", "seed", "tree_sha256"
_SHA256 = re.compile(r"[0-9a-f]{64}")
_DIGITS = re.compile(r"0|[1-9][0-9]{0,18}")


@dataclass(frozen=True)
class Declared:
    """Training settings as the uploader declares them; None: read from the model's metadata
    (``algorithm``, ``timesteps``, ``seed``, ``tree_sha256``), where ACV's own export and the
    CLI's SB3 conversion put them."""

    algorithm: str | None = None
    steps: int | None = None
    seed: int | None = None
    tree_sha256: str | None = None


def checked_declared(given: Declared, metadata: dict[str, str], role: ExperimentRole) -> Declared:
    """The declared settings, each from the upload or else the model's ``metadata``, checked:
    an advised policy names its tree's hash, a baseline or pilot policy names none.

    Raises:
        InputError: a setting missing from both, or out of range.
    """
    algorithm = given.algorithm if given.algorithm is not None else metadata.get(ALGORITHM_KEY)
    if algorithm is None or not algorithm.strip():
        raise InputError(
            "no declared algorithm: give it with the upload (algorithm; --algorithm) or in the "
            "model's "
            f"metadata_props ({ALGORITHM_KEY!r})"
        )
    if len(algorithm) > MAX_ALGORITHM or not algorithm.isprintable():
        raise InputError(
            f"the declared algorithm must be printable text of at most {MAX_ALGORITHM}"
        )
    steps = _number(given.steps, metadata, TIMESTEPS_KEY, "steps", 1, MAX_STEPS)
    seed = _number(given.seed, metadata, SEED_KEY, "seed", 0, MAX_SEED)
    tree = given.tree_sha256 if given.tree_sha256 is not None else metadata.get(TREE_KEY)
    tree = tree.strip().lower() if tree else None
    if tree is not None and not _SHA256.fullmatch(tree):
        raise InputError("tree_sha256 must be a SHA-256 in hex (64 digits 0-9, a-f)")
    if role == ExperimentRole.ADVISED and tree is None:
        raise InputError(
            "an advised policy declares the tree it trained with: give tree_sha256 "
            "(--tree-sha256; the experiment's is its spec's tree_sha256)"
        )
    if role != ExperimentRole.ADVISED and tree is not None:
        raise InputError(
            f"a {role.value} policy trains without advice: it has no tree_sha256 to declare"
        )
    return Declared(algorithm.strip(), steps, seed, tree)


def _number(
    given: int | None, metadata: dict[str, str], key: str, name: str, low: int, high: int
) -> int:
    if given is None:
        text = metadata.get(key)
        if text is None:
            raise InputError(
                f"no declared {name}: give it with the upload ({name}; --{name}) or in the model's "
                f"metadata_props ({key!r})"
            )
        if not _DIGITS.fullmatch(text):
            raise InputError(f"the model's metadata {key!r} is {text[:40]!r}, not a whole number")
        given = int(text)
    if isinstance(given, bool) or not low <= given <= high:
        raise InputError(f"the declared {name} must be in {low}..{high}, got {given}")
    return given
