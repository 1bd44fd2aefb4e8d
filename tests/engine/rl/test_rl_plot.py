"""Learning curves over runs and seeds."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.cli import main
from engine.errors import InputError
from engine.rl.plot import plot_runs, seed_band, seed_runs


def fake_run(path: Path, returns: list[float | None]) -> Path:
    path.mkdir(parents=True)
    rows = [{"timesteps": 100 * (i + 1), "return_100": r} for i, r in enumerate(returns)]
    (path / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_seed_band_is_mean_min_max_on_a_shared_grid() -> None:
    x = np.array([0.0, 10.0])
    grid, mean, lo, hi = seed_band([(x, np.array([0.0, 10.0])), (x, np.array([2.0, 20.0]))])
    assert grid[0] == 0.0 and grid[-1] == 10.0
    np.testing.assert_allclose(mean[[0, -1]], [1.0, 15.0])
    np.testing.assert_allclose(lo[[0, -1]], [0.0, 10.0])
    np.testing.assert_allclose(hi[[0, -1]], [2.0, 20.0])


def test_a_folder_of_runs_is_one_curve_over_seeds(tmp_path: Path) -> None:
    for seed in range(3):
        fake_run(tmp_path / "ppo" / f"seed{seed}", [None, 1.0 + seed, 2.0 + seed])
    assert len(seed_runs(tmp_path / "ppo")) == 3
    out = plot_runs([tmp_path / "ppo"], tmp_path / "c.png")
    assert Image.open(out).size == (840, 504)


def test_cli_takes_several_runs_after_one_flag(tmp_path: Path, monkeypatch) -> None:
    for name in ("ppo", "case1", "case2"):
        fake_run(tmp_path / name, [1.0, 2.0, 3.0])
    out = tmp_path / "curves.png"
    monkeypatch.setattr(
        sys,
        "argv",
        [
            "acv",
            "plot",
            "--runs",
            *(str(tmp_path / n) for n in ("ppo", "case1", "case2")),
            "--out",
            str(out),
        ],
    )
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code in (0, None) and out.is_file()


def test_a_run_without_episodes_is_an_input_error(tmp_path: Path) -> None:
    fake_run(tmp_path / "r", [None, None])
    with pytest.raises(InputError, match="no finished episode"):
        plot_runs([tmp_path / "r"], tmp_path / "c.png")
