"""``benchmarks/learning.py`` reads ACV's side from a validation's measures: the same settings
or a clear refusal, and what the run earned as its measures kept it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from engine.rl.config import TrainConfig
from engine.validation.design import Plan
from engine.validation.measure import training_end
from engine.validation.runs import measures_path, prepare, run_dir
from tests.support.benchmarks import load_benchmark

validation_return = load_benchmark("learning").validation_return

PLAN = Plan(env_id="Hopper-v5", teacher="orthogonal", timesteps=4096, seeds=2, arms=("n1", "p1-10"))


def _ppo(**change: object) -> TrainConfig:
    base = TrainConfig(algo="ppo", env_id="Hopper-v5", total_timesteps=4096, seed=1)
    return dataclasses.replace(base, **change)


@pytest.fixture
def validation(tmp_path: Path) -> Path:
    prepare(tmp_path, PLAN)
    run = run_dir(tmp_path, "n1", 1)
    run.mkdir(parents=True)
    rows = [{"timesteps": t, "return_100": r, "episode_length": 9, "z_mean": 1.0, "sps": 5}
            for t, r in ((2048, 10.0), (4096, 123.5))]  # fmt: skip
    (run / "metrics.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    measures_path(tmp_path, ("n1", 1)).parent.mkdir(parents=True)
    measures_path(tmp_path, ("n1", 1)).write_text(json.dumps({"train": training_end(run)}))
    return tmp_path


def test_a_measured_run_keeps_where_its_training_ended(validation: Path) -> None:
    kept = json.loads(measures_path(validation, ("n1", 1)).read_text())["train"]
    assert kept == {"timesteps": 4096, "return_100": 123.5, "episode_length": 9, "z_mean": 1.0}


def test_the_benchmark_reads_n1_from_the_measures_alone(validation: Path) -> None:
    for folder in (validation / "runs").iterdir():
        (folder / "metrics.jsonl").unlink()  # as on another machine: only the small files
    assert validation_return(_ppo(), validation) == 123.5


@pytest.mark.parametrize(
    ("change", "message"),
    [({"n_envs": 2}, "other settings"), ({"seed": 0}, "not measured n1 at seed 0")],
)
def test_the_benchmark_refuses_what_it_cannot_compare(
    validation: Path, change: dict, message: str
) -> None:
    with pytest.raises(SystemExit, match=message):
        validation_return(_ppo(**change), validation)


def test_the_difference_comes_with_welchs_interval() -> None:
    welch = load_benchmark("learning").welch_interval
    got = welch([700.0, 650.0, 600.0], [560.0, 540.0, 520.0])
    # by hand: difference 110; variances 2500 and 400 over 3, so se = sqrt(966.67) = 31.09;
    # Welch-Satterthwaite df = 966.67^2 / (833.33^2 / 2 + 133.33^2 / 2) = 2.62
    assert got["difference"] == 110.0
    assert got["df"] == 2.62
    half = got["ci95"][1] - 110.0
    assert half == pytest.approx(110.0 - got["ci95"][0], abs=0.1)
    assert 31.09 * 3.18 < half < 31.09 * 4.31  # t(0.975) between df 3 and df 2
    assert welch([700.0], [560.0, 540.0]) is None  # one seed: no interval
