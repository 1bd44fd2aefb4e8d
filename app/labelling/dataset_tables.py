"""The shared dataset's tables (issue 29 §4): each table's folder and typed columns, and
their Arrow schema; the card that lists them is :mod:`app.labelling.dataset_card`.

The folder that :mod:`app.labelling.dataset` writes::

    README.md                                    this card: configs, features, licence, citation
    data/train-00000-of-00001.parquet            labels: one row per labelled pair (default)
    candidates/train-00000-of-00001.parquet      the candidate states, with their images
    participants/train-00000-of-00001.parquet    who labelled, under pseudonyms
    trees/train-00000-of-00001.parquet           each finished participant's Preference Tree
    preferences/train-00000-of-00001.parquet     each answered pair as chosen and rejected states
    evaluations/train-00000-of-00001.parquet     agent evaluations' answers (only when any)

The labels sit in ``data/`` under the Hub's shard name because
``load_dataset("parquet", data_dir=DIR)`` reads no card: it takes the first file pattern that
matches, and ``data/{split}-NNNNN-of-NNNNN.*`` is tried first, so it loads the labels alone
(the other tables' columns differ, and one table cannot hold them). Every table is a config
of the card: ``load_dataset(DIR, "candidates")``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

SHARD = "train-00000-of-00001.parquet"


@dataclass(frozen=True)
class Column:
    """A column: its name, its kind (``int64``, ``float64``, ``string``, ``bool``,
    ``list<...>`` of one of these, or ``image``) and what it holds."""

    name: str
    kind: str
    doc: str


@dataclass(frozen=True)
class Table:
    """A table of the dataset: its config name, folder and columns."""

    name: str
    folder: str
    doc: str
    columns: tuple[Column, ...]

    @property
    def path(self) -> str:
        """The table's file, relative to the dataset folder."""
        return f"{self.folder}/{SHARD}"


PSEUDONYM = Column("participant", "string", "The participant's pseudonym (keyed hash of id).")
LABELS = Table(
    "labels",
    "data",
    "One row per labelled pair, grouped by participant in the order they labelled.",
    (
        PSEUDONYM,
        Column("kind", "string", "`bracket` (a match) or `disagreement` (asked after it)."),
        Column("round", "int64", "The bracket round, from 1; null for a disagreement pair."),
        Column("left", "int64", "The candidate shown on the left."),
        Column("right", "int64", "The candidate shown on the right."),
        Column("winner", "int64", "The candidate the participant preferred."),
        Column("side", "string", "`left` or `right`: the side chosen."),
        Column("tie", "bool", "The participant could not tell; the winner is a seeded coin's."),
        Column("stimulus", "string", "What the pair showed: `still` (pictures) or `clip`."),
        Column("response_ms", "int64", "Milliseconds from both pictures shown to the choice."),
    ),
)
CANDIDATES = Table(
    "candidates",
    "candidates",
    "The candidate states: enough to restore each in the environment, and its picture.",
    (
        Column("id", "int64", "The candidate id used by `left`, `right`, `winner` and trees."),
        Column("qpos", "list<float64>", "MuJoCo positions (`env.unwrapped.set_state`)."),
        Column("qvel", "list<float64>", "MuJoCo velocities."),
        Column("env_reward", "float64", "The environment reward R(s) of the state."),
        Column("baseline_return", "float64", "A no-advice agent's return from it, or null."),
        Column("image", "image", "The picture participants were shown."),
    ),
)
PARTICIPANTS = Table(
    "participants",
    "participants",
    "The participants who agreed to share their labels, under pseudonyms.",
    (
        PSEUDONYM,
        Column("external_id", "string", "Keyed hash of the crowd platform's id, or null."),
        Column("finished", "bool", "Whether they decided every match of their bracket."),
        Column("labels", "int64", "How many rows of `labels` are theirs."),
        Column("flags", "list<string>", "Label-quality flags (position bias, speed, ...)."),
        Column("reliability", "float64", "MACE competence from their known-answer checks."),
    ),
)
TREES = Table(
    "trees",
    "trees",
    "Each finished participant's Human Preference Tree, one entry per candidate id.",
    (
        PSEUDONYM,
        Column("champion", "int64", "The tree's root: the candidate that won the bracket."),
        Column("parent", "list<int64>", "Per candidate id, the candidate that beat it."),
        Column("height", "list<int64>", "Per candidate id, its dendrogram height."),
        Column("depth", "list<int64>", "Per candidate id, its depth (the root's is 1)."),
        Column("reward", "list<float64>", "Per candidate id, the tree reward T_r."),
        Column("document", "string", "The whole `acv.tree/1` JSON document."),
    ),
)
PREFERENCES = Table(
    "preferences",
    "preferences",
    "One row per answered pair, as reward learning reads it: both states, as arrays.",
    (
        PSEUDONYM,
        Column("kind", "string", "`bracket` or `disagreement`, as in `labels`."),
        Column("stimulus", "string", "What the pair showed: `still` (pictures) or `clip`."),
        Column("chosen", "int64", "The candidate preferred (the seeded coin's on a tie)."),
        Column("rejected", "int64", "The other candidate of the pair."),
        Column("tie", "bool", "The participant could not tell: read the pair as half each way."),
        Column("chosen_posture", "list<float64>", "`qpos` less the position on the floor."),
        Column("rejected_posture", "list<float64>", "The same for `rejected`."),
        Column("chosen_observation", "list<float64>", "The env's observation in that state."),
        Column("rejected_observation", "list<float64>", "The same for `rejected`."),
    ),
)
EVALUATOR = Column("evaluator", "string", "The evaluator's pseudonym (keyed hash of id).")
EVALUATIONS = Table(
    "evaluations",
    "evaluations",
    "One row per answered pair of an agent evaluation of this study's runs (issue 41): "
    "people shown what two trained agents do, asked which one does what was asked. Only "
    "evaluators who agreed to share their answers; present only when there are any.",
    (
        Column("evaluation", "int64", "The evaluation's id (one design, one question)."),
        Column(
            "evaluator_kind",
            "string",
            "`advisor` (whose tree trained the advised agents) or `others` (shown the "
            "study's instructions).",
        ),
        Column("question", "string", "What the evaluator was asked about every pair."),
        EVALUATOR,
        Column("position", "int64", "The pair's place in the evaluator's sequence, from 0."),
        Column("left_run", "string", "Keyed hash of the run shown on the left."),
        Column("left_arm", "string", "`advised` or `baseline`: the left run's arm."),
        Column("right_run", "string", "Keyed hash of the run shown on the right."),
        Column("right_arm", "string", "`advised` or `baseline`: the right run's arm."),
        Column("winner", "string", "`left`, `right`, or null when they could not tell."),
        Column("tie", "bool", 'The evaluator chose "can\'t tell".'),
        Column("response_ms", "int64", "Milliseconds from the pair shown to the choice."),
        Column("stimulus", "string", "What the pair showed of each agent: `still` or `clip`."),
        Column("reminder", "bool", "Whether the advisor's own bracket was shown as a reminder."),
        Column(
            "answered_on", "string", "The day it was answered (UTC, `YYYY-MM-DD`; no time of day)."
        ),
    ),
)
TABLES = (LABELS, CANDIDATES, PARTICIPANTS, TREES, PREFERENCES)


def arrow_schema(table: Table) -> Any:
    """The table's ``pyarrow.Schema``, with the ``datasets`` feature of its images in the
    metadata (the other columns' features follow from their Arrow types)."""
    import pyarrow as pa  # imported here: only exports need it

    fields = [pa.field(c.name, _arrow_type(pa, c.kind)) for c in table.columns]
    images = {c.name: {"_type": "Image"} for c in table.columns if c.kind == "image"}
    meta = {"huggingface": json.dumps({"info": {"features": images}})} if images else None
    return pa.schema(fields, metadata=meta)


def _arrow_type(pa: Any, kind: str) -> Any:
    if kind == "image":  # what datasets' Image feature stores
        return pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    if kind.startswith("list<"):
        return pa.list_(_arrow_type(pa, kind[5:-1]))
    return {"int64": pa.int64(), "float64": pa.float64(), "string": pa.string()}.get(
        kind, pa.bool_()
    )
