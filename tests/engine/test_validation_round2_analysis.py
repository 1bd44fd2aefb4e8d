"""Round 2's analysis on measures whose answer is known (no training): advised arms whose
scores follow their bracket's advice, shuffled arms that follow their shuffled tree, an
inverted arm against it, and a baseline with no taste. The primary must pass every criterion
and name each arm rightly; a missing measure is refused."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from engine.errors import InputError
from engine.treefile import dump_tree, load_tree
from engine.validation.round2 import SHUFFLE_SEED0, unrelated_tree
from engine.validation.round2_analysis import SCORES, write
from engine.validation.round2_runs import Round2Plan, arm_of, measures_path, tasks
from engine.verdict_bracket import alignment, tree_values

ROUND1 = Path(__file__).parents[2] / "docs/validation"
PLAN = Round2Plan(env_id="Humanoid-v5", timesteps=1_000_000, standing_bracket="standing")
#: each arm's pull toward (1) or away from (-1) its bracket's advice, or its shuffled tree
PULL = {"p1-10": 1.0, "bipars-em": 1.0, "p1-10-noisy": 1.0, "n3": -1.0}


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("round2")
    (folder / "advice").mkdir()
    (folder / "brackets").mkdir()
    values = {}
    for b in range(3):
        advice = replace(
            load_tree(ROUND1 / f"humanoid-orthogonal/brackets/bracket_{b}.json"), scores=None
        )
        shuffled = unrelated_tree(advice, np.random.default_rng(SHUFFLE_SEED0 + b))
        dump_tree(advice, folder / "advice" / f"advice-b{b}.json")
        dump_tree(shuffled, folder / "advice" / f"shuffled-b{b}.json")
        values[f"b{b}"] = (_z(tree_values(advice)), _z(tree_values(shuffled)))
    standing = load_tree(ROUND1 / "humanoid-standing/brackets/bracket_0.json")
    dump_tree(standing, folder / "brackets" / "standing.json")
    values["standing"] = (_z(tree_values(standing)), np.zeros(16))
    rng = np.random.default_rng(7)
    for label, seed in tasks(PLAN)[2:]:
        _write_measure(folder, label, seed, values, rng)
    return folder


def _z(v: np.ndarray) -> np.ndarray:
    return (v - v.mean()) / v.std()


def _write_measure(
    folder: Path, label: str, seed: int, values: dict, rng: np.random.Generator
) -> None:
    arm, bracket = arm_of(label)
    scores, truth = {}, 0.3 + rng.normal(0, 0.02)
    for name, (advice, shuffled) in values.items():
        taste = rng.normal(0, 0.6, 16)
        if bracket is not None and name == f"b{bracket}":
            taste += PULL.get(arm.name, 0.0) * advice + (arm.name == "n2-10") * shuffled
            truth += 0.3 * float(alignment(taste, advice))
        scores[name] = {score: taste.tolist() for score in SCORES}
    found = {"scores": scores, "truth": {"orthogonal": truth, "standing": 0.1}}
    path = measures_path(folder, (label, seed))
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(found))


def test_the_primary_passes_where_the_answer_is_known(out: Path) -> None:
    summary = write(out, PLAN, np.random.default_rng(0))
    primary = summary["scores"]["behaviour"]
    assert {c["name"].split()[0]: c["passed"] for c in primary["criteria"]} == {
        f"C{k}": True for k in (1, 3, 5, 7, 8, 4)
    }
    calls = {arm: v["outcome"] for arm, v in primary["verdicts"]["b0"].items()}
    assert calls["p1-10"] == calls["bipars-em"] == calls["p1-10-noisy"] == "used"
    assert calls["n2-10"] == "no-different" and calls["n3"] == "against"
    assert summary["truth"]["b0"]["p1-10"] == "follows"
    diagnostic = summary["scores"]["return"]
    assert diagnostic["role"] == "diagnostic"
    assert all(v["outcome"] is None for v in diagnostic["verdicts"]["b1"].values())
    assert summary["standing"]["verdict"]["outcome"] == "no-different"
    assert json.loads((out / "summary.json").read_text())["schema"] == "acv.validation-round2/1"
    assert "| behaviour | primary | C1" in (out / "report.md").read_text()


def test_a_missing_measure_is_named(out: Path, tmp_path: Path) -> None:
    path = measures_path(out, ("n2-10.b1", 103))
    kept = path.read_text()
    path.unlink()
    try:
        with pytest.raises(InputError, match="not measured yet: n2-10.b1-103"):
            write(out, PLAN, np.random.default_rng(0))
    finally:
        path.write_text(kept)
