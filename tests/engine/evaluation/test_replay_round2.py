"""The replay on round 2's runs (docs/validation.md §7.5), on fabricated measures files laid
out as ``acv validate-round2`` writes them: which runs make an arm, that the taste evaluator
reads the same runs' U under ``standing``, and that round 1's evaluators answer as there."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.evaluation.replay import BASELINE, criteria
from engine.evaluation.replay_round2 import (
    PLAIN_JUDGES,
    STANDING_TASTE,
    main,
    round2_arms,
    run_round2,
)

REPLAYS, BOOT = 5, 50


def write_runs(folder: Path, label: str, seeds: range, truth: dict[str, list[float]]) -> None:
    """One measures file per seed, holding only what the replay reads: U per teacher."""
    folder.mkdir(parents=True, exist_ok=True)
    for k, seed in enumerate(seeds):
        values = {teacher: u[k] for teacher, u in truth.items()}
        (folder / f"{label}-{seed}.json").write_text(json.dumps({"truth": values}))


def spread(centre: float, n: int = 5) -> list[float]:
    return list(centre + np.linspace(-0.02, 0.02, n))


@pytest.fixture
def humanoid(tmp_path: Path) -> Path:
    """``n1`` x 10, an arm better under orthogonal only, one better under standing only, an
    arm still training (3 runs) and a pilot."""
    folder = tmp_path / "measures"
    n1 = {"orthogonal": spread(0.3, 10), "standing": spread(0.1, 10)}
    n1["orthogonal"][5:] = [9.0] * 5  # seeds 105-109: never the baseline of an arm
    write_runs(folder, BASELINE, range(100, 110), n1)
    write_runs(
        folder, "p1-10.b0", range(100, 105), {"orthogonal": spread(0.6), "standing": spread(0.1)}
    )
    write_runs(
        folder, "n2-10.b0", range(100, 105), {"orthogonal": spread(0.3), "standing": spread(0.4)}
    )
    write_runs(
        folder,
        "p1-10.b1",
        range(100, 103),
        {"orthogonal": spread(0.6, 3), "standing": spread(0.1, 3)},
    )
    write_runs(
        folder, "pilot", range(2000, 2002), {"orthogonal": [0.2, 0.2], "standing": [0.1, 0.1]}
    )
    return folder


def test_an_arm_is_its_five_runs_against_n1s_first_five(humanoid: Path) -> None:
    ready, pending = round2_arms(humanoid)
    assert [arm.label for arm in ready] == ["n2-10.b0", "p1-10.b0"]
    assert pending == {"p1-10.b1": 3}
    arm = ready[1]
    assert arm.u[:5].tolist() == spread(0.6) and arm.u[5:].tolist() == spread(0.3, 10)[:5]
    assert arm.taste is not None and arm.taste[5:].tolist() == spread(0.1, 10)[:5]


def test_the_taste_evaluator_reads_the_same_runs_under_standing(humanoid: Path) -> None:
    arms_out, _ = run_round2(humanoid, "Humanoid-v5", REPLAYS, n_boot=BOOT)
    by_arm = {row["arm"]: row for row in arms_out}
    for key, truth, taste in (("p1-10.b0", "more", "U"), ("n2-10.b0", "unknown", "M")):
        row = by_arm[f"Humanoid-v5/{key}"]
        assert row["ground_truth"] == truth
        cells = {cell["evaluator"]: cell for cell in row["cells"]}
        assert list(cells) == [j.name for j in (*PLAIN_JUDGES, STANDING_TASTE)]
        own = cells[STANDING_TASTE.name]["own_test"]
        assert own == taste * REPLAYS  # fixed scores: the same own test in every replay
    # The plain teacher sees orthogonal's difference; the taste sees standing's.
    assert by_arm["Humanoid-v5/p1-10.b0"]["cells"][0]["rates"]["more"] == 1.0
    taste_cell = by_arm["Humanoid-v5/n2-10.b0"]["cells"][-1]
    assert taste_cell["rates"]["more"] == 1.0 and taste_cell["more_without_own_more"] == 0
    bound = {(r["arm"], r["evaluator"]) for r in criteria(arms_out)}
    assert ("Humanoid-v5/n2-10.b0", "lapses") in bound  # unknown truth: the false-rate rule
    assert ("Humanoid-v5/p1-10.b0", STANDING_TASTE.name) in bound


def test_runs_with_one_teacher_have_no_taste_evaluator(tmp_path: Path) -> None:
    folder = tmp_path / "measures"
    write_runs(folder, BASELINE, range(100, 110), {"orthogonal": spread(0.3, 10)})
    write_runs(folder, "p1-10.b0", range(100, 105), {"orthogonal": spread(0.6)})
    (row,), pending = run_round2(folder, "Hopper-v5", REPLAYS, n_boot=BOOT)
    assert pending == {}
    assert [cell["evaluator"] for cell in row["cells"]] == [j.name for j in PLAIN_JUDGES]


def test_the_command_writes_its_arms_pending_and_criteria(humanoid: Path, tmp_path: Path) -> None:
    out = tmp_path / "replay.json"
    main(["--measures", str(humanoid), "--env", "Humanoid-v5", "--out", str(out), "--replays", "2"])
    result = json.loads(out.read_text())
    assert result["pending"] == {"p1-10.b1": 3} and len(result["arms"]) == 2
    assert result["command"].endswith("--replays 2") and result["criteria"]
