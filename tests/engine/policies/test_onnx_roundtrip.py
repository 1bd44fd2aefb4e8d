"""Issue 44 §3, second check: an ACV-trained checkpoint exported to ONNX and imported gives
the same ``behaviour`` and ``return`` measures as the native path, within 1e-6.

The checkpoint is the bit-identity tests' ``judged.pt`` (a bipars-em run: its actor reads
z_phi(s), so the export carries the z network too) over their bracket ``advice.json``.

"Within 1e-6" is numpy's ``allclose`` with ``atol`` = ``rtol`` = 1e-6, not bit equality:
onnxruntime and numpy's BLAS sum the same float32 products in different orders, so the
actions differ by ~1e-7, and Humanoid's contacts amplify that over a rollout. Measured: the
behaviour scores (order 0.1) differ by 1.2e-7; the returns (up to 323) by 4.5e-5, 1.5e-7 of
their size.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch

from engine.envs import env_dims, make_env, restore
from engine.errors import InputError
from engine.policies.export import export_agent
from engine.policies.judging import imported_scores
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.rl.agent_judge import agent_scores
from engine.rl.config import TrainConfig
from engine.rl.judge_cache import ROLLOUT_DIR
from engine.rl.networks import Agent
from engine.rl.normalize import ObsNormalizer
from engine.rl.trained import TrainedAgent, deterministic_policy, load_agent
from engine.treefile import TreeDocument, load_tree

DATA = Path(__file__).parents[1] / "rl" / "data" / "bit_identity"
TOLERANCE = {"rtol": 1e-6, "atol": 1e-6}


@pytest.fixture(scope="module")
def trained() -> TrainedAgent:
    return load_agent(DATA / "judged.pt")


@pytest.fixture(scope="module")
def doc() -> TreeDocument:
    return load_tree(DATA / "advice.json")


def imported(trained: TrainedAgent) -> ImportedPolicy:
    """The checkpoint exported, then imported as an upload is: both files from bytes."""
    exported = export_agent(trained)
    env_id = trained.config.env_id
    obs_dim, act_dim = env_dims(env_id)
    model = check_onnx(exported.onnx, env_id=env_id, obs_dim=obs_dim, act_dim=act_dim)
    assert exported.normalisation is not None  # the run normalised its observations
    norm = ObsNormalisation.from_npz(exported.normalisation.to_npz(), obs_dim=obs_dim)
    return ImportedPolicy(model, norm)


def test_the_export_carries_the_env_and_the_declared_settings(trained: TrainedAgent) -> None:
    policy = imported(trained)
    assert policy.env_id == "Humanoid-v5"
    assert policy.model.metadata["algorithm"] == "acv bipars-em"
    assert policy.model.metadata["timesteps"] == str(trained.timesteps)
    assert policy.model.metadata["checkpoint_sha256"] == trained.digest


def test_the_exported_policy_acts_as_the_checkpoint(
    trained: TrainedAgent, doc: TreeDocument
) -> None:
    """At the candidates' observations and at observations far out (clipped by the normaliser)."""
    env = make_env(doc.env_id)
    try:
        observations = [restore(env, c.qpos, c.qvel) for c in doc.candidates]
    finally:
        env.close()
    rng = np.random.default_rng(0)
    observations += list(rng.normal(scale=50, size=(16, len(observations[0]))))
    native, onnx = deterministic_policy(trained), OnnxPolicy(imported(trained))
    for obs in observations:
        np.testing.assert_allclose(onnx(obs), native(obs), rtol=0, atol=1e-6)


@pytest.mark.parametrize("algo", ["ppo", "ppo-shaped", "bipars-mgl"])
def test_an_actor_without_z_and_without_normalisation_exports_too(algo: str) -> None:
    """Only bipars-em's actor reads z; a run without observation normalisation has none."""
    cfg = TrainConfig(algo=algo, env_id="Hopper-v5", norm_obs=False)
    torch.manual_seed(0)
    agent = Agent(11, 3, cfg.hidden, algo, cfg.z_max, cfg.z_init).eval()
    trained = TrainedAgent(cfg, agent, ObsNormalizer((11,), enabled=False), 0)
    exported = export_agent(trained)
    assert exported.normalisation is None
    model = check_onnx(exported.onnx, env_id="Hopper-v5", obs_dim=11, act_dim=3)
    assert "z.tanh" not in str(onnx.ModelProto.FromString(exported.onnx).graph.node)
    native, policy = deterministic_policy(trained), OnnxPolicy(ImportedPolicy(model))
    for obs in np.random.default_rng(1).normal(scale=3, size=(32, 11)):
        np.testing.assert_allclose(policy(obs), native(obs), rtol=0, atol=1e-6)


@pytest.mark.process
@pytest.mark.parametrize("judge", ["behaviour", "return"])
def test_imported_measures_equal_the_native_path(
    judge: str, trained: TrainedAgent, doc: TreeDocument, tmp_path: Path
) -> None:
    native = agent_scores(trained, doc, judge)  # the measure of test_bit_identity.py
    policy = imported(trained)
    got = imported_scores(policy, doc, judge, cache_dir=tmp_path)
    assert list(got) == list(native)
    np.testing.assert_allclose(list(got.values()), list(native.values()), **TOLERANCE)
    cached = list((tmp_path / ROLLOUT_DIR).iterdir())
    assert len(cached) == 1 and policy.digest[:16] in cached[0].name
    again = imported_scores(policy, doc, judge, cache_dir=tmp_path)  # from the cache: no child
    assert again == got


def test_the_other_judges_and_other_envs_are_refused(
    trained: TrainedAgent, doc: TreeDocument
) -> None:
    policy = imported(trained)
    with pytest.raises(InputError, match="judged by return or behaviour"):
        imported_scores(policy, doc, "shaped-value")
    other = dataclasses.replace(doc, env_id="HumanoidStandup-v5")
    with pytest.raises(InputError, match="the tree is for HumanoidStandup-v5"):
        imported_scores(policy, other, "return")
