"""``benchmarks/sb3_advice.py`` (issue 44): SB3 with and without ACV's advice wrapper next to
ACV's ``ppo-shaped`` and ``ppo``, at a tiny budget: every arm's result, each pair's verdict
under both judges, and a second call that reads the results back instead of training."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from engine.errors import InputError
from engine.pipeline import run_tournament
from engine.treefile import dump_tree, load_tree
from tests.support.benchmarks import load_benchmark

bench_module = load_benchmark("sb3_advice")
pytestmark = [pytest.mark.training, pytest.mark.slow]
SEEDS = [0, 1]


def _bench(out: Path):
    """ACV's settings but the budget (one rollout of 1024 steps), the judges' shortest
    rollouts, and a small bracket of the same teacher (a pilot's informative bracket of 16
    takes most of a minute to sample: the default, not tested here)."""
    tree = out / "given-tree.json"
    doc = run_tournament(env_id="Hopper-v5", n_candidates=6, p=0.9, seed=0, teacher="orthogonal")
    dump_tree(doc, tree)
    return bench_module.Bench(
        out=out,
        timesteps=1024,
        n_envs=1,
        num_steps=1024,
        tree=str(tree),
        episodes=1,
        max_steps=200,
        horizon=10,
    )


def test_four_arms_are_trained_judged_and_compared_then_read_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bench = _bench(tmp_path)
    summary = bench_module.run(bench, SEEDS)
    advice = load_tree(tmp_path / "advice.json")
    assert advice.env_id == "Hopper-v5" and advice.scores is None  # a person's tree
    assert summary["advice_scale"] == 10.0 and summary["primary"] == "behaviour"
    results = sorted(p.name for p in (tmp_path / "results").iterdir())
    arms = ("acv-ppo", "acv-ppo-shaped", "pilot", "sb3", "sb3-advice")
    assert results == sorted(
        f"{arm}-{s}.json" for arm in arms for s in ([2000, 2001] if arm == "pilot" else SEEDS)
    )
    for arm in ("sb3", "sb3-advice"):
        run = json.loads((tmp_path / "results" / f"{arm}-0.json").read_text())
        assert run["learner"] == "sb3" and run["timesteps"] == 1024
        assert set(run["scores"]) == {"behaviour", "return"}
        assert all(len(s) == len(advice.candidates) for s in run["scores"].values())
        assert (tmp_path / "runs" / f"{arm}-0" / "policy.onnx").is_file()
    assert [(p["advised"], p["baseline"]) for p in summary["pairs"]] == [
        ("sb3-advice", "sb3"),
        ("acv-ppo-shaped", "acv-ppo"),
    ]
    for pair in summary["pairs"]:
        assert set(pair["verdict"]) == {"behaviour", "return"}
        for found in pair["verdict"].values():
            assert found["outcome"] in {"used", "against", "no-different", "cannot-tell"}
            assert {"delta", "interval", "p_value"} <= set(found)
        for arm in (pair["advised"], pair["baseline"]):
            assert len(pair["env_return"][arm]["per_seed"]) == len(SEEDS)
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "results").iterdir()}
    bench_module.main(["--out", str(tmp_path), "--seeds", *map(str, SEEDS), "--timesteps", "1024",
                       "--n-envs", "1", "--num-steps", "1024", "--tree", bench.tree])  # fmt: skip
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "results").iterdir()} == stamps
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["pairs"] == json.loads(json.dumps(summary["pairs"]))
    with pytest.raises(InputError, match="timesteps"):  # another budget: not comparable
        bench_module.run(replace(bench, timesteps=2048), SEEDS)
