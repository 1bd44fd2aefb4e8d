"""The advice reward F(s) built from a Preference Tree document."""

from __future__ import annotations

import numpy as np
import pytest

from engine.advice import AdviceReward
from engine.errors import InputError
from engine.pipeline import run_tournament


@pytest.fixture(scope="module")
def hopper_doc():
    return run_tournament(env_id="Hopper-v5", n_candidates=12, p=0.9, seed=3, teacher="standing")


@pytest.mark.parametrize("mode", ["nearest", "softmax", "paper-min"])
@pytest.mark.parametrize("depth_factor", ["none", "paper"])
def test_batch_equals_one_at_a_time(hopper_doc, mode: str, depth_factor: str) -> None:
    advice = AdviceReward.from_tree(hopper_doc, mode=mode, depth_factor=depth_factor)
    qpos = np.stack([c.qpos for c in hopper_doc.candidates]) + np.random.default_rng(0).normal(
        scale=0.05, size=(12, 6)
    )
    batch = advice(qpos)
    assert batch.shape == (12,)
    assert np.allclose(batch, [advice(q[None])[0] for q in qpos])


def test_nearest_at_a_node_is_its_tree_reward(hopper_doc) -> None:
    advice = AdviceReward.from_tree(hopper_doc)
    qpos = np.stack([c.qpos for c in hopper_doc.candidates])
    rewards = [hopper_doc.tree.nodes[c.id].reward for c in hopper_doc.candidates]
    assert np.allclose(advice(qpos), rewards)


def test_paper_depth_factor_scales_by_depth(hopper_doc) -> None:
    advice = AdviceReward.from_tree(hopper_doc, depth_factor="paper")
    qpos = np.stack([c.qpos for c in hopper_doc.candidates])
    nodes = hopper_doc.tree.nodes
    expected = [nodes[c.id].reward * nodes[c.id].depth for c in hopper_doc.candidates]
    assert np.allclose(advice(qpos), expected)


def test_softmax_lies_between_node_values(hopper_doc) -> None:
    advice = AdviceReward.from_tree(hopper_doc, mode="softmax", kappa=3.0)
    f = advice(np.random.default_rng(1).normal(size=(50, 6)) * 0.3 + hopper_doc.candidates[0].qpos)
    assert (f >= advice.node_values.min() - 1e-9).all()
    assert (f <= advice.node_values.max() + 1e-9).all()


@pytest.mark.parametrize(("kwargs"), [{"mode": "max"}, {"depth_factor": "square"}])
def test_unknown_options_are_rejected(hopper_doc, kwargs) -> None:
    with pytest.raises(InputError):
        AdviceReward.from_tree(hopper_doc, **kwargs)
