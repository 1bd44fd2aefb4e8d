"""``acv validate-round2`` refuses bad settings with exit code 2 and trains nothing
(docs/validation.md §6; the round itself is hours of training, run by hand)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.cli import acv


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--env", "Walker2d-v5"], "round 2 is declared for Humanoid-v5 and Hopper-v5"),
        (["--jobs", "0"], "--jobs and --timesteps must be at least 1"),
        (["--stop-after", "5"], "--stop-after needs --runs"),
        (["--runs", "n1-100", "--stop-after", "-1"], "--stop-after must be a positive number"),
        (["--runs", "n1-0"], "n1-0 is not a run of round 2"),
        (["--runs", "p1-10.b0-100"], "p1-10.b0-100 trains on advice not made yet"),
        (["--standing-bracket", "/nonexistent.json"], "--standing-bracket: no file"),
    ],
)
def test_bad_settings_exit_2_with_a_message(tmp_path: Path, args: list[str], message: str) -> None:
    result = acv("validate-round2", "--out", tmp_path / "r2", *args)
    assert result.exit_code == 2 and message in result.stderr
    assert "Traceback" not in result.output + result.stderr
    assert not (tmp_path / "r2" / "runs").exists()  # nothing trained
