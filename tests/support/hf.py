"""A shared dataset (issue 29 §4) as its users load it: unzipped, and read with ``datasets``
(plain Parquet, and by the card's configs), with the checks every export must pass; and the
REST calls that make one (a participant agrees to share, the researcher downloads it)."""

from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path
from typing import Any

import yaml
from datasets import Dataset, Image, List, Value, load_dataset
from fastapi.testclient import TestClient

from engine.treefile import tree_from_json
from tests.support.studies import Player
from tests.support.web import ADMIN

CONFIGS = ("labels", "candidates", "participants", "trees", "preferences")
PSEUDONYM = re.compile(r"[0-9a-f]{32}")
SHARE = "/api/participants/me/share-consent"


def consent(player: Player, share: Any) -> Any:
    """``player`` says whether their labels may be shared (``share``: any JSON value)."""
    return player.client.put(SHARE, json={"share": share}, headers=player.headers)


def export(client: TestClient, study_id: int, query: str = "") -> Any:
    """The researcher's download of the study's ``dataset.zip``."""
    return client.get(f"/api/studies/{study_id}/export/dataset.zip{query}", headers=ADMIN)


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
    check_preferences(tables)


def check_preferences(tables: dict[str, Dataset]) -> None:
    """``preferences`` holds the labels' pairs, in their order, as the two states' arrays: a
    posture is the tail of its candidate's ``qpos``, and one candidate has one observation."""
    labels, pairs = tables["labels"], tables["preferences"]
    assert pairs.num_rows == labels.num_rows
    assert pairs.features["chosen_observation"] == List(Value("float64"))
    qpos = dict(zip(tables["candidates"]["id"], tables["candidates"]["qpos"], strict=True))
    seen: dict[int, list[float]] = {}
    for label, pair in zip(labels, pairs, strict=True):
        assert (pair["participant"], pair["kind"], pair["tie"]) == (
            label["participant"],
            label["kind"],
            label["tie"],
        )
        assert pair["chosen"] == label["winner"] and pair["stimulus"] == "still"
        assert {pair["chosen"], pair["rejected"]} == {label["left"], label["right"]}
        for side in ("chosen", "rejected"):
            posture, state = pair[f"{side}_posture"], qpos[pair[side]]
            assert 0 < len(posture) < len(state) and posture == state[len(state) - len(posture) :]
            observation = pair[f"{side}_observation"]
            assert seen.setdefault(pair[side], observation) == observation
