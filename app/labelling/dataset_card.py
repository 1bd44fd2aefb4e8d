"""The shared dataset's card (issue 29 §4): ``README.md`` with the Hub's YAML metadata (its
configs and features, from :mod:`app.labelling.dataset_tables`), licence and citation, and
what the data is and how it was collected."""

from __future__ import annotations

import re
from dataclasses import dataclass

from app.labelling.dataset_tables import (
    EVALUATIONS,
    LABELS,
    TABLES,
    Column,
    Table,
)
from engine import __version__
from engine.errors import InputError

DEFAULT_LICENSE = "cc-by-4.0"
#: A licence as the Hub names them (``cc-by-4.0``, ``mit``, ``other``).
_LICENSE = re.compile(r"[a-z0-9][a-z0-9.+-]{0,63}")
CITATION = """@misc{verma-acv,
  title  = {Advice Conformance Verification by Reinforcement Learning agents for
            Human-in-the-Loop},
  author = {Verma, Mudit and Kharkwal, Ayush and Kambhampati, Subbarao},
  note   = {SCAI, Arizona State University}
}"""


def check_license(license_id: str) -> str:
    """``license_id`` if it looks like a Hub licence id.

    Raises:
        InputError: it does not.
    """
    if not _LICENSE.fullmatch(license_id):
        raise InputError(
            f"license {license_id[:80]!r} is not a licence id such as {DEFAULT_LICENSE} or mit"
        )
    return license_id


def _feature(column: Column) -> dict[str, str]:
    """A column as the card's ``dataset_info`` lists it."""
    if column.kind == "image":
        return {"name": column.name, "dtype": "image"}
    if column.kind.startswith("list<"):
        return {"name": column.name, "list": column.kind[5:-1]}
    return {"name": column.name, "dtype": column.kind}


@dataclass(frozen=True)
class Facts:
    """What the card says about the study and the export."""

    name: str
    env_id: str
    n_candidates: int
    p: float
    seed: int
    sampling: str
    instructions: str
    participants: int
    labels: int
    trees: int
    license: str
    #: Answered evaluation pairs shared (:data:`EVALUATIONS`; the table is there only if any).
    evaluations: int = 0

    @property
    def tables(self) -> tuple[Table, ...]:
        """The dataset's tables: :data:`TABLES`, and :data:`EVALUATIONS` when it has rows."""
        return TABLES + ((EVALUATIONS,) if self.evaluations else ())


def readme(facts: Facts) -> str:
    """The dataset card: YAML metadata, then what the data is and how it was collected."""
    from huggingface_hub import DatasetCardData  # imported here: only exports need it

    meta = DatasetCardData(
        license=facts.license,
        pretty_name=f"ACV preference labels: {facts.name}",
        annotations_creators=["crowdsourced"],
        source_datasets=["original"],
        task_categories=["reinforcement-learning"],
        size_categories=[_size(facts.labels)],
        tags=["human-feedback", "preferences", "preference-tree", "mujoco", facts.env_id],
        configs=[
            {"config_name": t.name, "data_files": [{"split": "train", "path": t.path}]}
            | ({"default": True} if t is LABELS else {})
            for t in facts.tables
        ],
        dataset_info=[
            {"config_name": t.name, "features": [_feature(c) for c in t.columns]}
            for t in facts.tables
        ],
    )
    return f"---\n{meta.to_yaml()}\n---\n\n{_body(facts)}"


def _size(n: int) -> str:
    """The Hub's size category of ``n`` rows."""
    for bound, name in ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K")):
        if n < bound:
            return name
    return "100K<n<1M"


def _told(f: Facts) -> str:
    """The study's instructions as a quotation, when it has any."""
    lines = [line.strip() for line in f.instructions.strip().splitlines()]
    return "\n\nParticipants were told:\n\n" + "\n".join(f"> {x}" for x in lines) if lines else ""


def _evaluated(f: Facts) -> str:
    """What the ``evaluations`` config is, when the dataset has it."""
    if not f.evaluations:
        return ""
    return f"""## Agent evaluations

Agents were trained on these trees (advised) or without them (baseline), then people were
shown, pair by pair, what two agents do (`still` pictures or `clip`s) and asked which one
does what was asked: {f.evaluations} answers, in the `evaluations` config, from evaluators
who agreed to share them, under pseudonyms made like the participants'. Runs are named by
keyed hashes too, with their arm; the pair's sides were seeded. `reminder` says whether the
advisor's own bracket was shown beside the pair.

"""


def _body(f: Facts) -> str:
    tables = "\n\n".join(
        f"### `{t.name}` (`{t.path}`)\n\n{t.doc}\n\n| column | type | meaning |\n|---|---|---|\n"
        + "\n".join(f"| `{c.name}` | `{c.kind}` | {c.doc} |" for c in t.columns)
        for t in f.tables
    )
    return f"""# ACV preference labels: {f.name}

Pairwise preferences over robot states in `{f.env_id}`, collected with ACV (Advice
Conformance Verification) and exported by ACV {__version__}. Participants: {f.participants};
labels: {f.labels}; Human Preference Trees: {f.trees}.

## How it was collected

{f.n_candidates} candidate states were sampled (`{f.sampling}`, seed {f.seed}) from rollouts
of the environment and rendered. They were seeded into a single-elimination bracket with the
Braverman-Mossel noisy model (coin probability p = {f.p}). Each participant decided the
bracket's matches one pair at a time, round by round; some studies then ask a few extra
*disagreement* pairs. Each finished bracket gives a Human Preference Tree (the paper's
Algorithm 1): the champion at the root, under each state the states it beat.{_told(f)}

Only participants who agreed to have their labels shared in a public dataset, under a
pseudonym, are here, and none the researcher excluded. A participant is named by a keyed
hash (HMAC-SHA256 with a salt the researcher keeps secret) of their id, and their crowd
platform id likewise: the same study exported again gives the same pseudonyms, and they
cannot be traced back without the salt. Times of day are left out.

{_evaluated(f)}## Loading

```python
from datasets import load_dataset

labels = load_dataset("parquet", data_dir="DIR")  # the labels (data/)
candidates = load_dataset("DIR", "candidates")  # or "labels", "participants", "trees"
pairs = load_dataset("DIR", "preferences", split="train").with_format("numpy")
```

`preferences` is what reward-learning code reads: each answered pair's `chosen` and
`rejected` states as arrays, ready for a Bradley-Terry reward model (ACV's
`examples/bradley_terry.py` fits one).

## Tables

{tables}

## Citation

```bibtex
{CITATION}
```
"""
