"""A shared dataset (issue 29 §4) as its users load it: unzipped, and read with ``datasets``
(plain Parquet, and by the card's configs), with the checks every export must pass."""

from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path
from typing import Any

import yaml
from datasets import Dataset, Image, List, Value, load_dataset

from engine.treefile import tree_from_json

CONFIGS = ("labels", "candidates", "participants", "trees")
PSEUDONYM = re.compile(r"[0-9a-f]{32}")


def unzipped(body: bytes, into: Path) -> Path:
    """Extract a ``dataset.zip`` under ``into``; returns the one folder it holds."""
    with zipfile.ZipFile(io.BytesIO(body)) as archive:
        archive.extractall(into)
    (folder,) = into.iterdir()
    return folder


def card(folder: Path) -> dict[str, Any]:
    """The YAML metadata of the folder's ``README.md``."""
    text = (folder / "README.md").read_text()
    assert text.startswith("---\n")
    return yaml.safe_load(text.split("---\n")[1])


def load(folder: Path, cache: Path) -> dict[str, Dataset]:
    """Every table by its config name, as ``load_dataset(folder, name)`` gives it; and
    ``plain``: what ``load_dataset("parquet", data_dir=folder)`` loads."""
    tables = {
        name: load_dataset(str(folder), name, cache_dir=str(cache), split="train")
        for name in CONFIGS
    }
    plain = load_dataset("parquet", data_dir=str(folder), cache_dir=str(cache))
    assert list(plain) == ["train"]
    return tables | {"plain": plain["train"]}


def check_tables(tables: dict[str, Dataset], *, n_candidates: int) -> None:
    """What every export holds: the labels alone in plain Parquet, typed features, images
    that decode, pseudonyms everywhere, and trees that ``engine.treefile`` validates."""
    labels, candidates = tables["labels"], tables["candidates"]
    assert tables["plain"].column_names == labels.column_names
    assert tables["plain"].num_rows == labels.num_rows
    assert candidates.num_rows == n_candidates
    assert candidates.features["image"] == Image()
    assert candidates.features["qpos"] == List(Value("float64"))
    picture = candidates[0]["image"]
    assert picture.size[0] > 0 and candidates[0]["id"] == 0
    people = set(tables["participants"]["participant"])
    assert all(PSEUDONYM.fullmatch(p) for p in people)
    assert set(labels["participant"]) <= people and set(tables["trees"]["participant"]) <= people
    for tree in tables["trees"]:
        doc = tree_from_json(json.loads(tree["document"]))
        assert doc.judge == f"participant:{tree['participant']}"
        assert doc.tree.root == tree["champion"] and len(tree["parent"]) == n_candidates
        assert tree["parent"].count(None) == 1
