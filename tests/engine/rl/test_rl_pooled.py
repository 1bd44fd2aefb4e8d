"""Pooled advice: several people's trees over one bracket, F the mean of their F."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.advice import AdviceReward
from engine.errors import InputError
from engine.pipeline import replay_with_teacher, run_tournament
from engine.pooling import pooled_advice, pooled_tree
from engine.rl.advice_fn import pool_reward
from engine.rl.agent_judge import agent_scores, agent_tree
from engine.rl.checkpoint import find_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.runner import load_run_advice, load_run_pool, train
from engine.rl.trained import load_agent
from engine.treefile import TreeDocument, tree_to_json


@pytest.fixture(scope="module")
def people() -> list[TreeDocument]:
    standing = run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=4, teacher="standing")
    return [
        standing,
        replay_with_teacher(standing, "good"),
        replay_with_teacher(standing, "standing", noise=0.3),
    ]


def test_pooled_f_is_the_mean_of_the_members(people: list[TreeDocument]) -> None:
    qpos = np.stack([c.qpos for c in people[0].candidates]) + 0.01
    expected = np.mean([AdviceReward.from_tree(d)(qpos) for d in people], axis=0)
    np.testing.assert_allclose(pooled_advice(people)(qpos), expected)
    one = pooled_advice(people[:2])(qpos)
    assert not np.allclose(one, expected)


def test_the_pooled_verdict_ranks_by_mean_rounds_won(people: list[TreeDocument]) -> None:
    verdict = pooled_tree(people)
    assert verdict.judge == "pooled:standing,good,standing+noise0.3"
    assert verdict.first_round == people[0].first_round
    mean_height = {
        c.id: np.mean([d.tree.nodes[c.id].height for d in people]) for c in people[0].candidates
    }
    # at a candidate each tree's F is its tree reward r_e * height - r_b (similarity 1)
    for cid, score in verdict.scores.items():
        assert score == pytest.approx(mean_height[cid] - 1.0)
    assert pooled_tree([people[0], people[0]]).tree.root == people[0].tree.root


@pytest.mark.parametrize(
    "options", [{"depth_factor": "paper"}, {"mode": "softmax", "kappa": 2.0}], ids=str
)
def test_the_pooled_verdict_uses_the_runs_f_options(people: list[TreeDocument], options) -> None:
    """The pooled verdict is the bracket replayed by the same F the run trains with."""
    config = TrainConfig(
        env_id="Hopper-v5",
        algo="bipars-em",
        **{
            {"mode": "advice_mode", "kappa": "advice_kappa", "depth_factor": "advice_depth_factor"}[
                k
            ]: v
            for k, v in options.items()
        },
    )
    verdict = pooled_tree(people, **config.tree_options())
    qpos = np.stack([c.qpos for c in people[0].candidates])
    expected = pooled_advice(people, **config.tree_options())(qpos)
    np.testing.assert_allclose([verdict.scores[c.id] for c in people[0].candidates], expected)
    assert not np.allclose(expected, pooled_advice(people)(qpos))  # not nearest/none


def test_a_pool_needs_two_trees_over_one_bracket(people: list[TreeDocument]) -> None:
    with pytest.raises(InputError, match="at least two"):
        pooled_advice(people[:1])
    other = run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=5, teacher="standing")
    with pytest.raises(InputError, match="different brackets"):
        pooled_tree([people[0], other])


def test_the_configs_pool_weights_weight_f(people: list[TreeDocument]) -> None:
    """What a run trains with (``pool_reward``) is the weighted mean its verdict uses."""
    weights = (0.6, 0.1, 0.0)
    cfg = TrainConfig(env_id="Hopper-v5", algo="bipars-em", pool_weights=weights)
    qpos = np.stack([c.qpos for c in people[0].candidates]) + 0.01
    got = pool_reward(cfg, people)(qpos)
    np.testing.assert_allclose(got, pooled_advice(people, weights=weights)(qpos))
    assert not np.allclose(got, pooled_advice(people)(qpos))
    scores = pooled_tree(people, **cfg.tree_options(), weights=cfg.pool_weights).scores
    assert scores is not None
    np.testing.assert_allclose(
        np.array([scores[c.id] for c in people[0].candidates]),
        pooled_advice(people, weights=weights)(qpos - 0.01),
    )


@pytest.mark.parametrize(
    ("advice", "words"),
    [("pool", "2 pool weights for 3 pooled trees"), ("one", "need pooled advice")],
)
def test_pool_weights_need_one_per_pooled_tree(
    people: list[TreeDocument], tmp_path: Path, advice: str, words: str
) -> None:
    cfg = TrainConfig(env_id="Hopper-v5", algo="bipars-em", pool_weights=(1.0, 1.0))
    with pytest.raises(InputError, match=words):
        train(cfg, people if advice == "pool" else people[0], tmp_path / "run")
    assert not (tmp_path / "run").exists()  # refused before anything is written


@pytest.mark.training
def test_training_on_pooled_advice_saves_and_resumes_it(
    tmp_path: Path, people: list[TreeDocument]
) -> None:
    out = tmp_path / "pooled"
    cfg = TrainConfig(
        algo="bipars-em",
        env_id="Hopper-v5",
        total_timesteps=256,
        n_envs=2,
        num_steps=64,
        num_minibatches=4,
        update_epochs=1,
        checkpoint_every=128,
    )
    train(cfg, people, out)
    assert [tree_to_json(d) for d in load_run_pool(out)] == [tree_to_json(d) for d in people]
    assert load_run_advice(out).judge.startswith("pooled:")
    rows = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    (out / "checkpoints" / "step_256.pt").unlink()
    train(cfg, None, out, resume=True)  # the pool comes back from the run directory
    again = [json.loads(line) for line in (out / "metrics.jsonl").read_text().splitlines()]
    drop = ("sps", "time")
    assert [{k: v for k, v in r.items() if k not in drop} for r in again] == [
        {k: v for k, v in r.items() if k not in drop} for r in rows
    ]
    trained = load_agent(find_checkpoint(out))
    shaping = agent_scores(trained, people[0], "shaping", pooled_advice(people))
    doc = agent_tree(out, judge="shaping", advice=people[0])
    assert doc.scores == pytest.approx(shaping)
