"""A study's labels as a dataset that others can load (issue 29 §4): labels, candidates with
their states and pictures, participants and trees, and each answered pair as its chosen and
rejected states (``preferences``, :mod:`app.labelling.dataset_preferences`), as Parquet with a
dataset card (:mod:`app.labelling.dataset_card` says the folder's layout and columns).

Only participants who agreed to share (``share_consent``) and whom the researcher did not
exclude are in it, and only their labels and trees; likewise the answers of agent
evaluations of the study's runs, from evaluators who agreed (the ``evaluations`` config,
:mod:`app.labelling.dataset_evaluations`, there only when it has rows). Each is named by a
pseudonym: an HMAC-SHA256 of their id, and one of their crowd platform id, keyed with the
deployment's secret dataset salt (:func:`app.core.auth.dataset_salt`) and the study id. The
researcher keeps the salt, so an export made again names everyone the same way; without it,
nobody can reverse a pseudonym, even by trying every small id. The study id in the key keeps
one person's pseudonyms in two studies apart. Times of day are left out: with a platform's
submission log they could tell who a pseudonym is.
"""

from __future__ import annotations

import dataclasses
import io
import json
import zipfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.core.errors import ConflictError
from app.labelling import label_export, trees
from app.labelling.dataset_card import DEFAULT_LICENSE, Facts, check_license, readme
from app.labelling.dataset_evaluations import evaluation_rows
from app.labelling.dataset_preferences import preferences
from app.labelling.dataset_tables import (
    CANDIDATES,
    EVALUATIONS,
    LABELS,
    PARTICIPANTS,
    PREFERENCES,
    TREES,
    Table,
    arrow_schema,
)
from app.labelling.pseudonyms import Pseudonyms
from app.labelling.quality import quality
from app.models import Participant, Study, utcnow
from app.recruiting.seats import kept_in_data
from app.studies.images import image_file
from app.studies.service import get_study, list_candidates
from engine.errors import InputError
from engine.treefile import tree_to_json

Rows = list[dict[str, Any]]
#: What a participant ticks to agree (the consent and instructions pages say it alike).
SHARE_LABEL = "I agree that my labels may be shared in a public dataset, under a pseudonym."


@dataclass(frozen=True)
class Export:
    """The dataset folder's files (path relative to the folder -> bytes) and its facts."""

    files: dict[str, bytes]
    facts: Facts


def sharing(session: Session, *, study_id: int) -> list[Participant]:
    """The study's participants who agreed to share their labels and are in the data (not
    excluded, withdrawn or timed out: :func:`app.recruiting.seats.kept_in_data`)."""
    return list(
        session.scalars(
            select(Participant)
            .where(
                Participant.study_id == study_id,
                Participant.share_consent.is_(True),
                *kept_in_data(include_excluded=False, now=utcnow()),
            )
            .order_by(Participant.id)
        )
    )


def build(
    session: Session, *, study_id: int, salt: bytes, data_dir: Path, license: str = DEFAULT_LICENSE
) -> Export:
    """The dataset of the study's consenting participants, in memory.

    Raises:
        NotFoundError: no such study.
        ConflictError: nobody agreed to share, or none who did has labelled a pair.
        InputError: ``license`` is not a licence id.
    """
    check_license(license)
    study = get_study(session, study_id=study_id)
    people, hashes = _sharers(session, study_id), Pseudonyms(salt, study_id)
    names = {p.id: hashes.of("participant", p.id) for p in people}
    labels = _labels(session, study_id, names)
    if not labels:
        raise ConflictError(
            f"none of the {len(people)} participants of study {study_id} who agreed to share "
            "their labels has labelled a pair yet: there is nothing to export"
        )
    tables = {
        LABELS: labels,
        CANDIDATES: _candidates(session, study_id, data_dir),
        PARTICIPANTS: _participants(session, study_id, names, hashes, labels),
        TREES: _trees(session, people, names),
        PREFERENCES: preferences(labels, list_candidates(session, study_id=study_id), study.env_id),
    }
    if answers := evaluation_rows(session, study_id=study_id, hashes=hashes):
        tables[EVALUATIONS] = answers  # agent evaluations' sharing evaluators (issue 41)
    facts = _facts(study, len(people), tables, license)
    files = {t.path: _parquet(t, rows) for t, rows in tables.items()}
    return Export({"README.md": readme(facts).encode(), **files}, facts)


def _sharers(session: Session, study_id: int) -> list[Participant]:
    """:func:`sharing`, refusing a study where nobody shares."""
    people = sharing(session, study_id=study_id)
    if not people:
        raise ConflictError(
            f"study {study_id} has no participant who agreed to share their labels in a "
            "public dataset (or all who did are excluded): there is nothing to export"
        )
    return people


def _facts(study: Study, people: int, tables: dict[Table, Rows], license: str) -> Facts:
    """What the card says: the study's design and the export's counts."""
    return Facts(
        name=study.name,
        env_id=study.env_id,
        n_candidates=study.n_candidates,
        p=study.p,
        seed=study.seed,
        sampling=study.sampling,
        instructions=study.instructions,
        participants=people,
        labels=len(tables[LABELS]),
        trees=len(tables[TREES]),
        license=license,
        evaluations=len(tables.get(EVALUATIONS, [])),
    )


def _labels(session: Session, study_id: int, names: dict[int, str]) -> Rows:
    """The consenting participants' labels, grouped by pseudonym (not by who came first),
    each participant's in the order they gave them."""
    kept = ("kind", "round", "left", "right", "winner", "side", "tie", "stimulus", "response_ms")
    rows = [
        {"participant": names[r["participant_id"]]} | {k: r[k] for k in kept}
        for r in label_export.records(session, study_id=study_id)
        if r["participant_id"] in names
    ]
    return sorted(rows, key=lambda r: r["participant"])


def _candidates(session: Session, study_id: int, data_dir: Path) -> Rows:
    """Every candidate with its state and its full-size picture's bytes."""
    rows = []
    for c in list_candidates(session, study_id=study_id):
        path = image_file(data_dir, c.image_path)
        if not path.is_file():
            raise ConflictError(f"the picture of candidate {c.id} is missing from the data dir")
        image = {"bytes": path.read_bytes(), "path": f"candidate-{c.id:03d}{path.suffix}"}
        rows.append(
            {
                "id": c.id,
                "qpos": list(c.qpos),
                "qvel": list(c.qvel),
                "env_reward": c.env_reward,
                "baseline_return": c.baseline_return,
                "image": image,
            }
        )
    return rows


def _participants(
    session: Session, study_id: int, names: dict[int, str], hashes: Pseudonyms, labels: Rows
) -> Rows:
    """One row per consenting participant, with their quality flags and reliability."""
    counts = Counter(r["participant"] for r in labels)
    rows = [
        {
            "participant": names[q.participant.id],
            "external_id": None
            if q.participant.external_id is None
            else hashes.of("external", q.participant.external_id),
            "finished": q.participant.finished_at is not None,
            "labels": counts[names[q.participant.id]],
            "flags": q.flags,
            "reliability": q.reliability,
        }
        for q in quality(session, study_id=study_id).participants
        if q.participant.id in names
    ]
    return sorted(rows, key=lambda r: r["participant"])


def _trees(session: Session, people: list[Participant], names: dict[int, str]) -> Rows:
    """The Preference Tree of every consenting participant who finished, judged by their
    pseudonym (a tree document names its judge)."""
    rows = []
    for person in people:
        if person.finished_at is None:
            continue
        doc = trees.participant_tree(session, participant_id=person.id)
        doc = dataclasses.replace(doc, judge=f"participant:{names[person.id]}")  # not their id
        nodes = [doc.tree.nodes[c.id] for c in doc.candidates]
        rows.append(
            {
                "participant": names[person.id],
                "champion": doc.tree.root,
                "parent": [n.parent for n in nodes],
                "height": [n.height for n in nodes],
                "depth": [n.depth for n in nodes],
                "reward": [n.reward for n in nodes],
                "document": json.dumps(tree_to_json(doc)),
            }
        )
    return sorted(rows, key=lambda r: r["participant"])


def _parquet(table: Table, rows: Rows) -> bytes:
    import pyarrow as pa  # imported here: only exports need it
    import pyarrow.parquet as pq

    buffer = io.BytesIO()
    pq.write_table(pa.Table.from_pylist(rows, schema=arrow_schema(table)), buffer)
    return buffer.getvalue()


def write_folder(export: Export, out: Path) -> None:
    """Write the dataset's files under ``out``, a new or empty folder.

    Raises:
        InputError: ``out`` is a file, or a folder that is not empty.
    """
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"{out} is not an empty folder: write the dataset to a new one")
    for name, data in export.files.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_bytes(data)


def zipped(export: Export, *, folder: str) -> bytes:
    """The dataset's files in a zip, inside one ``folder`` (what unzipping makes)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in export.files.items():
            archive.writestr(f"{folder}/{name}", data)
    return buffer.getvalue()
