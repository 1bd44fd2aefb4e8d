"""BiPaRS learns how much to trust the advice: z stays with good advice, drops with harmful.

InvertedPendulum-v5 pays R = 1 per step while the pole is up (|angle| <= 0.2), so F = R is
good advice and F = -R is harmful (with z = 1 the shaped reward is 0). PPO learns to
balance the pole within 10k steps, which is enough for z_phi to move. Final mean z measured
over seeds 0-7: ``bipars-em`` (10k steps) good [0.93, 1.03], harmful [0.66, 0.82];
``bipars-mgl`` (15k steps; its one-step meta-gradient moves z more slowly at first) good
[0.98, 1.06], harmful [0.40, 0.88].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.rl.config import TrainConfig
from engine.rl.logger import read_metrics
from engine.rl.runner import train

pytestmark = pytest.mark.training


def pole_up(qpos: np.ndarray) -> np.ndarray:
    """InvertedPendulum-v5's reward as a function of the state: 1 while the pole is up."""
    return (np.abs(qpos[:, 1]) <= 0.2).astype(float)


STEPS = {"bipars-em": 10_240, "bipars-mgl": 15_360}


def final_z(algo: str, sign: float, seed: int, out: Path) -> float:
    cfg = TrainConfig(
        algo=algo,
        env_id="InvertedPendulum-v5",
        total_timesteps=STEPS[algo],
        n_envs=4,
        num_steps=128,
        num_minibatches=8,
        update_epochs=4,
        seed=seed,
        checkpoint_every=10**9,
    )
    train(cfg, lambda q: sign * pole_up(q), out)
    rows = read_metrics(out)
    assert all(-cfg.z_max < r["z_mean"] < cfg.z_max for r in rows)
    return rows[-1]["z_mean"]


def check_drift(algo: str, seed: int, tmp_path: Path) -> None:
    good = final_z(algo, +1.0, seed, tmp_path / "good")
    bad = final_z(algo, -1.0, seed, tmp_path / "bad")
    assert good >= 0.9, f"z fell to {good:.3f} with good advice"
    assert bad <= 0.9, f"z = {bad:.3f} with harmful advice (good advice: {good:.3f})"


@pytest.mark.parametrize("algo", ["bipars-em", "bipars-mgl"])
def test_z_keeps_good_advice_and_drops_harmful_advice(algo: str, tmp_path: Path) -> None:
    check_drift(algo, 0, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3, 4])
@pytest.mark.parametrize("algo", ["bipars-em", "bipars-mgl"])
def test_z_drift_holds_across_seeds(algo: str, seed: int, tmp_path: Path) -> None:
    check_drift(algo, seed, tmp_path)
