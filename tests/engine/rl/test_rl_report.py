"""The behaviour judge, advice mode ``reward`` (F = R) and the per-checkpoint report."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.errors import InputError
from engine.judges import JUDGES
from engine.pipeline import run_tournament
from engine.rl.agent_judge import agent_tree
from engine.rl.behaviour import RolloutOptions, occupancy_scores
from engine.rl.checkpoint import find_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.judge_cache import ROLLOUT_DIR, file_digest
from engine.rl.logger import read_metrics
from engine.rl.report import CheckpointReport, checkpoint_report
from engine.rl.reward_terms import candidate_terms
from engine.rl.runner import train
from engine.rl.trained import load_agent
from engine.treefile import TreeDocument, tree_to_json

pytestmark = pytest.mark.training

SMALL = dict(
    env_id="Hopper-v5",
    total_timesteps=512,
    n_envs=2,
    num_steps=64,
    num_minibatches=4,
    update_epochs=2,
    checkpoint_every=256,
)
FEW = RolloutOptions(episodes=3, max_steps=300, burn_in=5)


@pytest.fixture(scope="module")
def standing() -> TreeDocument:
    return run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=3, teacher="standing")


@pytest.fixture(scope="module")
def run(tmp_path_factory, standing: TreeDocument) -> Path:
    out = tmp_path_factory.mktemp("report") / "case2"
    train(TrainConfig(algo="bipars-em", **SMALL), standing, out)
    return out


@pytest.fixture(scope="module")
def reward_run(tmp_path_factory, standing: TreeDocument) -> Path:
    out = tmp_path_factory.mktemp("report") / "case1"
    train(TrainConfig(algo="bipars-em", advice_mode="reward", **SMALL), standing, out)
    return out


def test_behaviour_scores_read_the_visited_states(standing: TreeDocument) -> None:
    near_0 = np.repeat(standing.candidates[0].qpos[None], 5, axis=0)
    near_5 = np.repeat(standing.candidates[5].qpos[None], 5, axis=0)
    a, b = occupancy_scores(near_0, standing), occupancy_scores(near_5, standing)
    assert a[0] == pytest.approx(1.0) and max(a, key=a.get) == 0
    assert b[5] == pytest.approx(1.0) and max(b, key=b.get) == 5
    assert a == occupancy_scores(near_0, standing)  # a function of the states alone


def test_the_behaviour_judge_is_deterministic_and_cached(run: Path) -> None:
    first = agent_tree(run, 512, "behaviour", rollouts=FEW)
    digest = file_digest(find_checkpoint(run, 512))[:16]
    cache = list((run / ROLLOUT_DIR).glob(f"behaviour.{digest}.*.npy"))
    assert len(cache) == 1
    again = agent_tree(run, 512, "behaviour", rollouts=FEW)
    assert tree_to_json(again) == tree_to_json(first)
    visited = np.load(cache[0])
    assert visited.ndim == 2 and 1 <= len(visited) <= FEW.max_steps


def test_the_behaviour_judge_reads_its_rollouts(run: Path, standing: TreeDocument) -> None:
    agent_tree(run, 256, "behaviour", rollouts=FEW)
    digest = file_digest(find_checkpoint(run, 256))[:16]
    cache = next((run / ROLLOUT_DIR).glob(f"behaviour.{digest}.*.npy"))
    np.save(cache, np.repeat(standing.candidates[2].qpos[None], 4, axis=0))  # other states
    doc = agent_tree(run, 256, "behaviour", rollouts=FEW)
    assert doc.tree.root == 2 and doc.scores[2] == pytest.approx(1.0)


def test_rollout_options_are_validated() -> None:
    with pytest.raises(InputError, match="episodes >= 1"):
        RolloutOptions(episodes=0)


def test_reward_mode_shapes_with_the_step_reward(reward_run: Path) -> None:
    rows = read_metrics(reward_run)
    assert all(r["f_mean"] > 0.5 for r in rows)  # F = R: Hopper's healthy reward is 1 a step
    assert '"advice_mode": "reward"' in (reward_run / "config.json").read_text()


def test_reward_mode_judges_with_f_equal_to_r(reward_run: Path, standing: TreeDocument) -> None:
    terms = candidate_terms(load_agent(find_checkpoint(reward_run)), standing)
    np.testing.assert_allclose(terms.advice, terms.reward)
    np.testing.assert_allclose(terms.shaped, terms.reward * (1 + terms.z))


def test_the_report_holds_every_judge_and_the_table(run: Path, standing: TreeDocument) -> None:
    report = checkpoint_report(run, 512, rollouts=FEW)
    assert set(report.judges) == set(JUDGES) and report.step == 512
    for name, result in report.judges.items():
        assert result.tree.judge == f"agent:{name}@512"
        assert result.conformance.n_matches == len(standing.matches)
    rows = {row.id: row for row in report.candidates}
    assert sorted(rows) == [c.id for c in standing.candidates]
    for judge, column in (
        ("shaped", "shaped"),
        ("shaped-value", "value"),
        ("behaviour", "behaviour"),
        ("return", "env_return"),
        ("shaping", "shaping"),
    ):
        scores = report.judges[judge].tree.scores
        assert all(scores[i] == pytest.approx(getattr(rows[i], column)) for i in rows)
    for row in rows.values():
        assert row.shaping == pytest.approx(row.z * row.advice)
        assert row.shaped == pytest.approx(row.reward + row.shaping)


def test_the_report_round_trips_through_json(run: Path) -> None:
    report = checkpoint_report(run, 256, rollouts=FEW)
    obj = report.to_json()
    assert obj["schema"] == "acv.checkpoint/1"
    assert CheckpointReport.from_json(obj).to_json() == obj
    with pytest.raises(InputError, match="acv.checkpoint/1"):
        CheckpointReport.from_json({"schema": "other"})


def test_a_report_stored_before_the_rename_reads_value_as_shaped_value(run: Path) -> None:
    obj = checkpoint_report(run, 256, rollouts=FEW).to_json()
    obj["judges"] = {("value" if k == "shaped-value" else k): v for k, v in obj["judges"].items()}
    obj["judges"] = {k: v for k, v in obj["judges"].items() if k != "return"}
    for row in obj["candidates"]:
        del row["env_return"]
    old = CheckpointReport.from_json(obj)
    assert "shaped-value" in old.judges and "value" not in old.judges
    assert old.judges["shaped-value"].judge == "shaped-value"
    assert all(row.env_return is None for row in old.candidates)


def test_a_run_without_advice_needs_the_tree_to_compare_with(
    tmp_path: Path, standing: TreeDocument
) -> None:
    out = tmp_path / "ppo"
    train(TrainConfig(algo="ppo", **{**SMALL, "total_timesteps": 256}), None, out)
    with pytest.raises(InputError, match="without advice"):
        checkpoint_report(out)
    report = checkpoint_report(out, advice=standing, rollouts=FEW)
    assert all(row.z == 0 and row.advice == 0 for row in report.candidates)
