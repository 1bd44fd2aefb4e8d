"""``acv reproduce`` end to end on a tiny budget: outputs, resume, a participant's tree."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from PIL import Image
from typer.testing import CliRunner

from app.cli import cli
from app.reproduce.analysis import posture_classes, recent_episode_length
from app.reproduce.plan import ARMS, run_path
from app.reproduce.report import _draw_least_conformant
from engine.treefile import load_tree

TINY = ["--env", "Hopper-v5", "--timesteps", "256", "--n-envs", "2", "--num-steps", "64",
        "--checkpoint-every", "128", "--candidates", "6"]
FIGURES = ["figure3", "figure4-case1", "figure4-case2", "figure4-control", "conformance"]


def acv(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _mtimes(out: Path) -> dict[str, int]:
    return {str(p): p.stat().st_mtime_ns for p in (out / "runs").rglob("*.pt")}


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("reproduce") / "results"
    result = acv("reproduce", "--out", out, *TINY)
    assert result.exit_code == 0, result.output
    return out


def test_writes_figures_summary_and_readme(results: Path) -> None:
    for name in FIGURES:
        with Image.open(results / f"{name}.png") as img:
            assert img.width > 300 and img.height > 200
        assert (results / f"{name}.svg").read_text().lstrip().startswith("<?xml")
    summary = json.loads((results / "summary.json").read_text())
    assert list(summary["arms"]) == [arm.name for arm in ARMS]
    for arm in ARMS:
        seed = summary["arms"][arm.name]["seeds"][0]
        assert seed["timesteps"] == 256
        assert seed["final_episode_length_100"] is None or seed["final_episode_length_100"] >= 1
        if arm.advice is not None:
            curve = seed["conformance_curve"]
            assert [r["step"] for r in curve] == [128, 256]
            assert all(set(r) >= {"bent_share", "z_mean_straight", "z_mean_bent"}
                       for r in curve)
            least = min(curve, key=lambda r: (r["match_agreement"], r["step"]))
            expected = None if least["match_agreement"] >= curve[-1]["match_agreement"] \
                else least["step"]
            assert seed["least_conformant_step"] == expected
            assert (results / f"figure4-{arm.name}-least.png").is_file() == (expected is not None)
            if arm.algo == "ppo-shaped":  # z is fixed at 1 wherever a class has candidates
                assert {r["z_mean_straight"] for r in curve} <= {1.0, None}
            assert seed["final"]["conformance"]["n_matches"] == 5
    assert summary["arms"]["ppo"]["seeds"][0]["z_mean_final"] == 0.0
    assert summary["arms"]["control"]["seeds"][0]["z_mean_final"] == 1.0
    assert [type(p["holds"]) for p in summary["predictions"]] == [bool] * 5
    readme = (results / "README.md").read_text()
    assert "| claim | paper | measured | holds? |" in readme
    assert all(f"]({name}.png)" in readme for name in FIGURES)


def test_the_least_conformant_checkpoint_gets_its_own_figure(results: Path,
                                                             tmp_path: Path) -> None:
    arm = next(a for a in ARMS if a.name == "case2")
    advice = load_tree(results / "advice" / "standing.json")
    classes = posture_classes(advice)
    curve = [{"step": 128, "match_agreement": 0.4}, {"step": 256, "match_agreement": 0.8}]
    run = run_path(results, arm, 0)
    assert _draw_least_conformant(tmp_path, arm, run, advice, curve, classes, {}) == 128
    with Image.open(tmp_path / "figure4-case2-least.png") as img:
        assert img.width > 300
    curve[0]["match_agreement"] = 0.8  # no lower than at the end: nothing more to show
    (tmp_path / "figure4-case2-least.png").unlink()
    assert _draw_least_conformant(tmp_path, arm, run, advice, curve, classes, {}) is None
    assert not (tmp_path / "figure4-case2-least.png").exists()


def test_both_cases_share_one_bracket(results: Path) -> None:
    good, standing = (json.loads((results / "advice" / f"{n}.json").read_text())
                      for n in ("good", "standing"))
    assert (good["judge"], standing["judge"]) == ("good", "standing")
    assert good["first_round"] == standing["first_round"]
    def states(doc: dict) -> list:
        return [(c["qpos"], c["qvel"], c["env_reward"]) for c in doc["candidates"]]

    assert states(good) == states(standing)


def test_a_second_call_resumes_without_retraining(results: Path) -> None:
    before = _mtimes(results)
    last = results / "runs" / "case2" / "seed_0" / "checkpoints" / "step_256.pt"
    last.unlink()  # as if the reproduction had been cut off after step 128
    result = acv("reproduce", "--out", results, *TINY)
    assert result.exit_code == 0, result.output
    after = _mtimes(results)
    assert last.is_file()
    assert {k: v for k, v in after.items() if k != str(last)} == \
        {k: v for k, v in before.items() if k != str(last)}


@pytest.mark.parametrize(("args", "message"), [
    (["--timesteps", "512"], "other settings (timesteps)"),
    (["--seeds", "0"], "--seeds must be at least 1"),
    (["--p", "1.5"], "--p must be in [0, 1]"),
    (["--study", "1"], "--study and --participant go together"),
    (["--env", "CartPole-v1"], "not a MuJoCo env"),
])
def test_bad_input_is_one_line_and_exit_2(results: Path, args: list[str], message: str) -> None:
    options = dict(zip(TINY[::2], TINY[1::2], strict=True)) | dict(zip(args[::2], args[1::2],
                                                                       strict=True))
    result = acv("reproduce", "--out", results, *[x for kv in options.items() for x in kv])
    assert result.exit_code == 2, result.output
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_a_participants_tree_is_the_case_2_advice(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv("ACV_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.setenv("DATABASE_URL", f"sqlite:///{tmp_path / 'acv.sqlite3'}")
    created = acv("study", "create", "--name", "r", "--env", "Hopper-v5", "--candidates", "6")
    study = re.search(r"study (\d+) ready", created.output)[1]
    simulated = acv("simulate", "--study", study, "--teacher", "standing")
    participant = re.search(r"participant (\d+)", simulated.output)[1]
    out = tmp_path / "results"
    result = acv("reproduce", "--out", out, "--study", study, "--participant", participant,
                 *TINY)
    assert result.exit_code == 0, result.output
    advice = json.loads((out / "advice" / "standing.json").read_text())
    assert advice["judge"] == f"participant:{participant}"
    wrong = acv("reproduce", "--out", tmp_path / "other", "--study", "99", "--participant",
                participant, *TINY)
    assert wrong.exit_code == 2 and "not in study 99" in wrong.stderr


def test_recent_episode_length_weighs_updates_by_their_episodes() -> None:
    rows = [{"episodes": 300, "episode_length": 10.0}, {"episodes": 0, "episode_length": None},
            {"episodes": 60, "episode_length": 20.0}, {"episodes": 40, "episode_length": 50.0}]
    assert recent_episode_length(rows) == (60 * 20 + 40 * 50) / 100
    assert recent_episode_length(rows, episodes=101) == (300 * 10 + 60 * 20 + 40 * 50) / 400
    assert recent_episode_length(rows[1:2]) is None
