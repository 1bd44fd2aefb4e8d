"""The shared dataset's ``preferences`` config (issue 44 §5), on PostgreSQL: a real
study, labelled through the REST API by participants who prefer the state with the higher
environment reward (one of them once cannot tell), is downloaded as ``dataset.zip`` and loaded
with ``datasets``; and the documented example, ``examples/bradley_terry.py``, run as a user
runs it, fits a Bradley-Terry reward model that explains those labels."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import torch
from fastapi.testclient import TestClient

from engine.envs import env_dims
from tests.support.hf import consent, export, load, unzipped
from tests.support.studies import Player
from tests.support.web import ADMIN

# postgres_only: fitting a reward model to an export is the subject, not storage.
pytestmark = pytest.mark.postgres_only

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "bradley_terry.py"
N_CANDIDATES, PLAYERS = 8, 3


def play_by_reward(player: Player, reward: dict[int, float], *, tie_first: bool) -> None:
    """Decide every match for the state with the higher R, or tie the first one."""
    if tie_first:
        match = player.next_match()
        assert player.label(match["match_id"], None, tie=True).status_code == 201
    player.play(lambda m: max(m["a"]["candidate_id"], m["b"]["candidate_id"], key=reward.get))


def exported(client: TestClient, make_study: Any, invite: Any, into: Path) -> Path:
    """The unzipped dataset of a Hopper study that ``PLAYERS`` participants labelled."""
    study_id = make_study(n_candidates=N_CANDIDATES, allow_ties=True)["id"]
    listed = client.get(f"/api/studies/{study_id}/candidates", headers=ADMIN).json()
    reward = {c["id"]: c["env_reward"] for c in listed}
    for i in range(PLAYERS):
        player = invite(study_id)
        assert consent(player, True).status_code == 200
        play_by_reward(player, reward, tie_first=i == 0)
    response = export(client, study_id)
    assert response.status_code == 200, response.text
    return unzipped(response.content, into)


def run_example(folder: Path, cache: Path, *args: str) -> dict[str, Any]:
    """``python examples/bradley_terry.py FOLDER ARGS --json`` in a fresh interpreter."""
    done = subprocess.run(
        [sys.executable, str(EXAMPLE), str(folder), *args, "--json"],
        env=os.environ | {"HF_DATASETS_CACHE": str(cache), "HF_HUB_OFFLINE": "1"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_the_example_fits_a_reward_model_to_a_real_export(
    client, make_study, invite, tmp_path: Path
) -> None:
    folder = exported(client, make_study, invite, tmp_path / "zip")
    pairs = load(folder, tmp_path / "cache")["preferences"]  # load() runs check_preferences
    assert pairs.num_rows == PLAYERS * (N_CANDIDATES - 1) and sum(pairs["tie"]) == 1
    assert set(pairs["kind"]) == {"bracket"}
    assert len(pairs[0]["chosen_observation"]) == env_dims("Hopper-v5")[0]

    report = run_example(folder, tmp_path / "hf", "--out", str(tmp_path / "reward.pt"))
    assert report["pairs"] == pairs.num_rows and report["ties"] == 1
    assert report["features"] == "observation" and report["dim"] == env_dims("Hopper-v5")[0]
    assert report["loss"] < report["chance_loss"] / 2 and report["accuracy"] >= 0.9
    saved = torch.load(tmp_path / "reward.pt", weights_only=True)
    assert saved["mean"].shape == (report["dim"],)

    spec = importlib.util.spec_from_file_location("bradley_terry", EXAMPLE)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    args = [str(folder), "--features", "posture", "--cache-dir", str(tmp_path / "hf"), "--json"]
    posture = example.main(args)
    assert posture["dim"] == len(pairs[0]["chosen_posture"]) and posture["accuracy"] >= 0.9
    again = example.main(args)
    assert again == posture  # seeded: the same data give the same model
