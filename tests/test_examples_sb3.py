"""The documented example ``examples/sb3_hopper_advice.py`` (issue 44 §1), at a tiny budget:
SB3 PPO trains on Hopper-v5 inside ``DummyVecEnv`` with the advice wrapper, and the files it
leaves are what ACV's import takes. The test reads those files back on its own: the ONNX passes
the gate and, with the ``.npz`` normaliser, acts as SB3's own ``PPO.load`` of the ``.zip``
predicts; the example's episode adds R and the advice term into the reward it reports; and the
same tree and seed give the same ONNX file."""

from __future__ import annotations

import hashlib
import importlib.util
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

from engine.envs import env_dims
from engine.policies.normalisation import ObsNormalisation
from engine.policies.onnx_check import check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.treefile import load_tree

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sb3_hopper_advice.py"
ENV = "Hopper-v5"
#: One PPO update: 2 envs x 32 steps, one minibatch of 64.
TINY = ["--timesteps", "64", "--n-envs", "2", "--n-steps", "32", "--json"]

pytestmark = pytest.mark.training


def load_example() -> ModuleType:
    """The example as a module, imported from its file as a user's script would run."""
    spec = importlib.util.spec_from_file_location("sb3_hopper_advice", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def example() -> Iterator[ModuleType]:
    """The example module; torch's thread count, which it sets to 1 as ACV's runner does, is
    put back for the tests that follow in this process."""
    threads = torch.get_num_threads()
    yield load_example()
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def report(example: ModuleType, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("example")
    result: dict[str, Any] = example.main([*TINY, "--out", str(out)])
    return result


def observations(n: int = 64) -> np.ndarray:
    """States Hopper visits under random actions, and some far out (clipped by the
    normaliser)."""
    env, rows = gym.make(ENV), []
    obs, _ = env.reset(seed=1)
    env.action_space.seed(1)
    for _ in range(n // 2):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        rows.append(obs)
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    far = np.random.default_rng(1).normal(scale=20, size=(n - len(rows), len(obs)))
    return np.concatenate([np.array(rows), far])


def test_the_files_are_what_an_import_takes(report: dict[str, Any]) -> None:
    files = {k: Path(v) for k, v in report["files"].items()}
    tree = Path(report["tree"])
    assert load_tree(tree).env_id == ENV
    assert report["tree_sha256"] == hashlib.sha256(tree.read_bytes()).hexdigest()
    assert report["declared"] == {"num_timesteps": 64, "seed": 0, "n_envs": 2}
    data = files["onnx"].read_bytes()
    obs_dim, act_dim = env_dims(ENV)
    model = check_onnx(data, env_id=ENV, obs_dim=obs_dim, act_dim=act_dim)
    assert report["env_id"] == model.env_id == ENV
    assert report["onnx_sha256"] == model.digest == hashlib.sha256(data).hexdigest()


def test_the_onnx_policy_acts_as_sb3_predicts(report: dict[str, Any]) -> None:
    """SB3's own load of the ``.zip`` (the test's file, so unpickling it is safe here) is the
    reference; the ONNX runs with the ``.npz`` normaliser, as ACV's judges run it."""
    from stable_baselines3 import PPO

    files = {k: Path(v) for k, v in report["files"].items()}
    obs_dim, act_dim = env_dims(ENV)
    model = check_onnx(files["onnx"].read_bytes(), env_id=ENV, obs_dim=obs_dim, act_dim=act_dim)
    norm = ObsNormalisation.from_npz(files["normalisation"].read_bytes(), obs_dim=obs_dim)
    obs = observations()
    expected, _ = PPO.load(files["sb3"], device="cpu").predict(norm(obs), deterministic=True)
    got = np.clip(OnnxPolicy(ImportedPolicy(model, norm)).actions(obs), -1.0, 1.0)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-5)
    assert report["episode"]["max_action_difference"] <= 1e-5


def test_the_episode_reward_is_r_plus_the_advice(report: dict[str, Any]) -> None:
    played = report["episode"]
    assert played["steps"] >= 1
    assert played["shaped"] == pytest.approx(played["R"] + played["F"], rel=1e-12)
    assert played["F"] > 0.0  # offset 1 keeps each step's scale * (F + 1) >= 0


def test_the_same_tree_and_seed_give_the_same_policy(
    example: ModuleType, report: dict[str, Any], tmp_path: Path
) -> None:
    """``--tree`` with the first run's tree file: a user's tree takes the same path."""
    again = example.main([*TINY, "--tree", report["tree"], "--out", str(tmp_path)])
    assert again["tree"] == report["tree"]
    assert again["onnx_sha256"] == report["onnx_sha256"]
    assert again["episode"] == report["episode"]
