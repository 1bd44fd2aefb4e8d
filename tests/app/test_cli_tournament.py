"""``acv tournament`` and ``acv compare`` as a user runs them (subprocesses)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def acv(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "app.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("trees")
    for name in ("a", "b"):
        r = acv("tournament", "--env", "Hopper-v5", "--candidates", "6", "--seed", "4",
                "--teacher", "standing", "--out", f"{name}.json", cwd=d)
        assert r.returncode == 0, r.stderr
    r = acv("tournament", "--replay", "a.json", "--teacher", "good", "--out", "good.json", cwd=d)
    assert r.returncode == 0, r.stderr
    return d


def test_same_seed_gives_identical_bytes(trees: Path) -> None:
    assert (trees / "a.json").read_bytes() == (trees / "b.json").read_bytes()


def test_compare_json(trees: Path) -> None:
    r = acv("compare", "a.json", "good.json", "--json", cwd=trees)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert {"match_agreement", "match_agreement_ci", "kendall_tau_b", "tree_edit_distance",
            "same_champion", "rejected"} <= set(out)
    assert out["n_matches"] == 5
    assert len(out["rejected"]) == out["n_matches"] - out["n_agree"]


def test_compare_table_against_itself(trees: Path) -> None:
    r = acv("compare", "a.json", "a.json", cwd=trees)
    assert r.returncode == 0 and "5/5 = 1.000" in r.stdout


@pytest.mark.parametrize("args", [
    ["tournament", "--candidates", "1", "--out", "x.json"],
    ["tournament", "--p", "1.5", "--out", "x.json"],
    ["tournament", "--env", "NoSuchEnv-v0", "--out", "x.json"],
    ["tournament", "--teacher", "oracle", "--out", "x.json"],
    ["tournament", "--replay", "missing.json", "--teacher", "good", "--out", "x.json"],
    ["compare", "a.json", "garbage.txt"],
    ["compare", "a.json", "other.json"],
])
def test_bad_input_is_one_line_and_exit_2(trees: Path, args: list[str]) -> None:
    (trees / "garbage.txt").write_text("{not json")
    if not (trees / "other.json").exists():
        acv("tournament", "--env", "Hopper-v5", "--candidates", "6", "--seed", "9",
            "--teacher", "good", "--out", "other.json", cwd=trees)
    r = acv(*args, cwd=trees)
    assert r.returncode == 2
    assert r.stderr.startswith("acv: error:") and len(r.stderr.strip().splitlines()) == 1
    assert "Traceback" not in r.stderr
