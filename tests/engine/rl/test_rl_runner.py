"""A training run as a library call: artefacts, checkpoints, resume, cancellation."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from engine import __version__
from engine.errors import InputError
from engine.rl.checkpoint import list_checkpoints, load_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.logger import read_metrics
from engine.rl.runner import train

pytestmark = pytest.mark.training

ROW_KEYS = {
    "timesteps",
    "episodic_return",
    "shaped_return",
    "z_mean",
    "z_std",
    "sps",
    "policy_loss",
    "value_loss",
    "f_mean",
    "f_std",
}


def advice(qpos: np.ndarray) -> np.ndarray:
    """A toy F: the pole's angle should stay small."""
    return -np.abs(qpos[:, 1])


def tiny(algo: str = "bipars-em", **kwargs) -> TrainConfig:
    base = dict(
        algo=algo,
        env_id="InvertedPendulum-v5",
        total_timesteps=1024,
        n_envs=2,
        num_steps=64,
        num_minibatches=4,
        update_epochs=2,
        checkpoint_every=512,
        seed=3,
    )
    return TrainConfig(**{**base, **kwargs})


def stripped(rows: list[dict]) -> list[dict]:
    """Metrics rows without the wall-clock fields."""
    return [{k: v for k, v in r.items() if k not in ("sps", "time")} for r in rows]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("runs") / "em"
    rows = []
    last = train(tiny(), advice, out, progress=rows.append)
    assert last == out / "checkpoints" / "step_1024.pt"
    assert [r["timesteps"] for r in rows] == list(range(128, 1025, 128))
    return out


def test_a_run_writes_all_artefacts(run: Path) -> None:
    assert TrainConfig.from_json(json.loads((run / "config.json").read_text())) == tiny()
    assert json.loads((run / "provenance.json").read_text())["acv"] == __version__
    rows = read_metrics(run)
    assert len(rows) == 8 and all(set(r) >= ROW_KEYS for r in rows)
    assert any(r["episodic_return"] is not None for r in rows)
    assert list(run.glob("events.out.tfevents.*"))
    assert list(list_checkpoints(run)) == [512, 1024]
    state = load_checkpoint(run / "checkpoints" / "step_1024.pt")
    assert {"agent", "obs_norm", "reward_scaler", "optimizer", "z_optimizer", "config"} <= set(
        state
    )
    assert not list((run / "checkpoints").glob(".tmp-*"))


@pytest.mark.parametrize(("algo", "z"), [("ppo", 0.0), ("ppo-shaped", 1.0)])
def test_logged_f_and_z_are_the_runs_own(tmp_path: Path, algo: str, z: float) -> None:
    """A constant F = -0.25 with advice-scale 2 is logged as f_mean -0.5, f_std 0; z is the
    algorithm's fixed weight (0 for ppo, which only logs F; 1 for ppo-shaped)."""

    def constant(qpos: np.ndarray) -> np.ndarray:
        return np.full(len(qpos), -0.25)

    train(tiny(algo, total_timesteps=256, advice_scale=2.0), constant, tmp_path / algo)
    for row in read_metrics(tmp_path / algo):
        assert (row["f_mean"], row["f_std"], row["z_mean"], row["z_std"]) == (-0.5, 0.0, z, 0.0)


def test_learned_z_varies_across_states(run: Path) -> None:
    assert all(row["z_std"] > 0.0 for row in read_metrics(run))


@pytest.mark.parametrize("algo", ["bipars-mgl", "ppo"])
def test_resume_after_a_stop_matches_an_uninterrupted_run(tmp_path: Path, algo: str) -> None:
    cfg = tiny(algo, total_timesteps=768, checkpoint_every=256)
    train(cfg, advice, tmp_path / "whole")
    calls = iter(range(100))
    stopped = train(cfg, advice, tmp_path / "cut", should_stop=lambda: next(calls) == 2)
    assert stopped.name == "step_384.pt"  # a stop writes a checkpoint at once
    train(cfg, advice, tmp_path / "cut", resume=True)
    assert stripped(read_metrics(tmp_path / "cut")) == stripped(read_metrics(tmp_path / "whole"))


def test_resume_drops_metrics_rows_written_after_the_last_checkpoint(
    run: Path, tmp_path: Path
) -> None:
    out = tmp_path / "killed"
    shutil.copytree(run, out)
    (out / "checkpoints" / "step_1024.pt").unlink()  # as if killed between 512 and 1024
    train(tiny(), advice, out, resume=True)
    assert stripped(read_metrics(out)) == stripped(read_metrics(run))


def test_bad_runs_are_refused(run: Path, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="already holds a run"):
        train(tiny(), advice, run)
    with pytest.raises(InputError, match="config differs in seed"):
        train(tiny(seed=4), advice, run, resume=True)
    with pytest.raises(InputError, match="needs advice"):
        train(tiny(), None, tmp_path / "none")
    with pytest.raises(InputError, match="no checkpoints"):
        train(tiny(), advice, tmp_path / "empty", resume=True)
    assert not (tmp_path / "none").exists()


def test_resume_drops_a_metrics_line_torn_by_a_kill(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "torn"
    shutil.copytree(run, out)
    (out / "checkpoints" / "step_1024.pt").unlink()
    with (out / "metrics.jsonl").open("a") as f:
        f.write('{"timesteps": 1152, "update": 9, "episodic_re')  # kill -9 mid-write
    assert len(read_metrics(out)) == 8  # readers skip it too
    train(tiny(), advice, out, resume=True)
    assert stripped(read_metrics(out)) == stripped(read_metrics(run))


def test_a_damaged_metrics_line_before_the_last_is_an_input_error(
    run: Path, tmp_path: Path
) -> None:
    out = tmp_path / "damaged"
    shutil.copytree(run, out)
    lines = (out / "metrics.jsonl").read_text().splitlines()
    lines[2] = lines[2][:20]
    (out / "metrics.jsonl").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 3 is not JSON"):
        read_metrics(out)


def test_a_failed_start_leaves_nothing_that_blocks_a_retry(tmp_path: Path) -> None:
    bad = tiny(env_id="NoSuchEnv-v0")
    with pytest.raises(InputError, match="unknown env"):
        train(bad, advice, tmp_path / "new")
    assert not (tmp_path / "new").exists()
    made = tmp_path / "made"  # a directory the caller created (the web app's worker does)
    made.mkdir()
    (made / "note.txt").write_text("mine")
    with pytest.raises(InputError, match="unknown env"):
        train(bad, advice, made)
    assert [p.name for p in made.iterdir()] == ["note.txt"]
    train(tiny(total_timesteps=128), advice, made)  # not refused as "already holds a run"
    assert (made / "config.json").is_file()


def test_a_start_failing_after_writing_removes_what_it_wrote(tmp_path: Path, monkeypatch) -> None:
    import engine.rl.runner as runner

    def broken_logger(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(runner, "RunLogger", broken_logger)
    with pytest.raises(OSError, match="disk full"):
        train(tiny(), advice, tmp_path / "new")
    assert not (tmp_path / "new").exists()
    (tmp_path / "made").mkdir()
    with pytest.raises(OSError, match="disk full"):
        train(tiny(), advice, tmp_path / "made")
    assert not list((tmp_path / "made").iterdir())


@pytest.mark.parametrize("content", [b"", b"not a checkpoint", b"PK\x03\x04broken zip"])
def test_corrupt_checkpoints_are_input_errors(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "step_1.pt"
    path.write_bytes(content)
    with pytest.raises(InputError, match="not a readable checkpoint"):
        load_checkpoint(path)
