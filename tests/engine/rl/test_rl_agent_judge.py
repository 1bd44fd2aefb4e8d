"""The Agent Preference Tree of a trained run, over the advice tree's bracket."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from engine.advice import AdviceReward
from engine.conformance import compare
from engine.envs import make_env, restore
from engine.errors import InputError
from engine.judges import JUDGES
from engine.pipeline import run_tournament
from engine.rl.agent_judge import agent_scores, agent_tree
from engine.rl.checkpoint import find_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.reward_terms import candidate_terms, candidate_z, judge_reward
from engine.rl.runner import train
from engine.rl.trained import load_agent
from engine.treefile import TreeDocument, load_tree, tree_from_json, tree_to_json

pytestmark = pytest.mark.training


@pytest.fixture(scope="module")
def good_tree() -> TreeDocument:
    return run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=1, teacher="good")


@pytest.fixture(scope="module")
def run(tmp_path_factory, good_tree: TreeDocument) -> Path:
    out = tmp_path_factory.mktemp("judge") / "good"
    cfg = TrainConfig(
        algo="bipars-em",
        env_id="Hopper-v5",
        total_timesteps=512,
        n_envs=2,
        num_steps=64,
        num_minibatches=4,
        update_epochs=2,
        checkpoint_every=256,
    )
    train(cfg, good_tree, out)
    return out


@pytest.mark.parametrize("judge", JUDGES)
def test_agent_tree_is_a_valid_tree_over_the_same_bracket(
    run: Path, good_tree: TreeDocument, judge: str
) -> None:
    doc = agent_tree(run, judge=judge)
    assert doc.judge == f"agent:{judge}@512"
    assert doc.first_round == good_tree.first_round
    assert [c.id for c in doc.candidates] == [c.id for c in good_tree.candidates]
    assert len(doc.tree.nodes) == len(good_tree.candidates)
    assert tree_to_json(tree_from_json(tree_to_json(doc))) == tree_to_json(doc)
    assert 0.0 <= compare(good_tree, doc).match_agreement <= 1.0


def test_advice_tree_is_saved_with_the_run(run: Path, good_tree: TreeDocument) -> None:
    assert tree_to_json(load_tree(run / "advice.json")) == tree_to_json(good_tree)


def test_shaped_judge_is_reward_plus_weighted_shaping(run: Path, good_tree: TreeDocument) -> None:
    trained = load_agent(find_checkpoint(run, 256))
    shaped = agent_scores(trained, good_tree, "shaped")
    shaping = agent_scores(trained, good_tree, "shaping")
    reward = candidate_terms(trained, good_tree).reward
    for i, c in enumerate(good_tree.candidates):
        assert shaped[c.id] == pytest.approx(reward[i] + shaping[c.id])


def test_the_judges_r_is_the_reward_the_agent_gets(run: Path, good_tree: TreeDocument) -> None:
    # the stored env_reward has no action; the agent pays the control cost of its own mean
    # action, ctrl_cost_weight * |a|^2 (Hopper: 1e-3), so the judge subtracts it
    trained = load_agent(find_checkpoint(run, 256))
    env = make_env("Hopper-v5")
    obs = np.stack([restore(env, c.qpos, c.qvel) for c in good_tree.candidates])
    x = torch.from_numpy(trained.obs_norm(obs))
    with torch.no_grad():
        mean = trained.agent.actor(x, trained.agent.z(x)).double().numpy().clip(-1, 1)
    cost = 1e-3 * (mean**2).sum(1)
    reward = candidate_terms(trained, good_tree).reward
    stored = np.array([c.env_reward for c in good_tree.candidates])
    assert (cost > 0).all()
    np.testing.assert_allclose(reward, stored - cost, rtol=1e-9)


def test_judge_reward_is_the_r_of_the_judges(run: Path, good_tree: TreeDocument) -> None:
    trained = load_agent(find_checkpoint(run, 256))
    reward = judge_reward(trained, good_tree)
    terms = candidate_terms(trained, good_tree).reward
    assert list(reward) == [c.id for c in good_tree.candidates]
    np.testing.assert_array_equal(list(reward.values()), terms)
    stored = np.array([c.env_reward for c in good_tree.candidates])
    assert (np.array(list(reward.values())) < stored).all()  # minus a control cost


def test_value_is_the_old_name_of_shaped_value(run: Path) -> None:
    old, new = agent_tree(run, judge="value"), agent_tree(run, judge="shaped-value")
    assert old.judge == new.judge == "agent:shaped-value@512"
    assert tree_to_json(old) == tree_to_json(new)


def test_the_return_judge_replays_with_the_policys_returns(run: Path) -> None:
    doc = agent_tree(run, judge="return")
    assert doc.scores is not None and len(set(doc.scores.values())) > 1
    assert all(np.isfinite(v) for v in doc.scores.values())


def test_a_good_advice_agent_reproduces_the_human_tree(run: Path, good_tree: TreeDocument) -> None:
    # Case 1 of the paper: the good teacher's winners have the higher R and, having won more
    # rounds, the higher T_r = F at the candidates; with z ~ 1, g = R + z F agrees everywhere
    result = compare(good_tree, agent_tree(run, judge="shaped"))
    assert result.match_agreement == 1.0 and result.tree_edit_distance == 0.0


def test_bad_inputs(run: Path, tmp_path: Path) -> None:
    other = run_tournament(
        env_id="InvertedPendulum-v5", n_candidates=4, p=0.9, seed=0, teacher="good"
    )
    with pytest.raises(InputError, match="trained on Hopper-v5"):
        agent_tree(run, advice=other)
    with pytest.raises(InputError, match="no checkpoint at step 7"):
        agent_tree(run, step=7)
    with pytest.raises(InputError, match="unknown judge"):
        agent_tree(run, judge="vibes")
    foreign = tmp_path / "step_5.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(InputError, match="not an ACV checkpoint"):
        load_agent(foreign)


def test_the_judge_uses_the_advice_the_agent_trained_on(run: Path, good_tree: TreeDocument) -> None:
    # another bracket over other candidates: it supplies the players, not the agent's F
    other = run_tournament(env_id="Hopper-v5", n_candidates=8, p=0.9, seed=7, teacher="standing")
    doc = agent_tree(run, judge="shaping", advice=other)
    qpos = np.stack([c.qpos for c in other.candidates])
    z = candidate_z(load_agent(find_checkpoint(run)), other)
    own_f = AdviceReward.from_tree(good_tree)(qpos)  # the run's config: nearest, scale 1
    other_f = AdviceReward.from_tree(other)(qpos)
    assert not np.allclose(own_f, other_f)  # the two trees' F really differ here
    for c, f in zip(other.candidates, own_f, strict=True):
        assert doc.scores[c.id] == pytest.approx(z[c.id] * f)
