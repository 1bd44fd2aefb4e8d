"""A Stable-Baselines3 save converted to ONNX without unpickling (issue 44 §2): a real PPO
MlpPolicy acts as SB3's deterministic ``predict`` does, to 1e-5; anything else is refused
before a byte is unpickled, and every member is size-capped before it is read."""

from __future__ import annotations

import io
import json
import os
import pickle
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

from engine.errors import InputError
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.policies.sb3 import Sb3Limits, sb3_to_onnx
from tests.support.onnx_models import ACT_DIM, ENV, OBS_DIM
from tests.support.zips import BREAKS, broken_first_member


def observations(n: int = 64) -> np.ndarray:
    """States Hopper visits under random actions, and some far out."""
    env, rows = gym.make(ENV), []
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(n // 2):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        rows.append(obs)
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return np.concatenate([np.array(rows), rng.normal(scale=3, size=(n - len(rows), OBS_DIM))])


@pytest.mark.training
@pytest.mark.parametrize("activation", ["tanh", "relu"])
def test_a_ppo_mlp_policy_acts_as_sb3_predicts(activation: str, tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    kwargs = {} if activation == "tanh" else {"activation_fn": torch.nn.ReLU, "net_arch": [32, 16]}
    model = PPO(
        "MlpPolicy", ENV, n_steps=64, batch_size=64, n_epochs=2, seed=0, policy_kwargs=kwargs
    )
    model.learn(total_timesteps=192)
    model.save(tmp_path / "ppo.zip")
    converted = sb3_to_onnx((tmp_path / "ppo.zip").read_bytes(), env_id=ENV, activation=activation)
    assert converted.declared["num_timesteps"] == 192 and converted.declared["seed"] == 0
    assert all(not isinstance(v, dict | list) for v in converted.declared.values())
    obs = observations()
    expected, _ = model.predict(obs, deterministic=True)  # the mean, clipped to the box
    got = np.clip(OnnxPolicy(ImportedPolicy(converted.model)).actions(obs), -1.0, 1.0)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-5)


def tensors(*shapes: tuple[int, ...]) -> list[torch.Tensor]:
    generator = torch.Generator().manual_seed(0)
    return [torch.randn(*s, generator=generator) for s in shapes]


def mlp_state(hidden: int = 8) -> dict[str, torch.Tensor]:
    """An MlpPolicy-shaped state dict for Hopper-v5, made by hand."""
    w0, b0, w2, b2, wa, ba = tensors(
        (hidden, OBS_DIM), (hidden,), (hidden, hidden), (hidden,), (ACT_DIM, hidden), (ACT_DIM,)
    )
    return {
        "log_std": torch.zeros(ACT_DIM),
        "mlp_extractor.policy_net.0.weight": w0,
        "mlp_extractor.policy_net.0.bias": b0,
        "mlp_extractor.policy_net.2.weight": w2,
        "mlp_extractor.policy_net.2.bias": b2,
        "mlp_extractor.value_net.0.weight": w0.clone(),
        "mlp_extractor.value_net.0.bias": b0.clone(),
        "action_net.weight": wa,
        "action_net.bias": ba,
        "value_net.weight": torch.ones(1, hidden),
        "value_net.bias": torch.zeros(1),
    }


def pth(state: object) -> bytes:
    buffer = io.BytesIO()
    torch.save(state, buffer)
    return buffer.getvalue()


def sb3_zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return buffer.getvalue()


class Planted:
    """Unpickling this runs a shell command: the test checks it never runs."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self) -> tuple[object, ...]:
        return (os.system, (f"touch {self.marker}",))


def settings(**extra: object) -> bytes:
    return json.dumps({"num_timesteps": 1000, "seed": 3, "policy_kwargs": {}} | extra).encode()


def test_a_hand_made_mlp_policy_is_converted_and_pickled_fields_are_left_unread(
    tmp_path: Path,
) -> None:
    marker = tmp_path / "ran"
    planted = {":type:": "<class 'x'>", ":serialized:": pickle.dumps(Planted(marker)).hex()}
    data = sb3_zip({"data": settings(policy_class=planted), "policy.pth": pth(mlp_state())})
    converted = sb3_to_onnx(data, env_id=ENV)
    assert converted.declared == {"num_timesteps": 1000, "seed": 3}
    assert converted.model.metadata["activation"] == "tanh"
    assert not marker.exists()


def test_a_weights_file_that_would_run_code_is_refused(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    data = sb3_zip({"data": settings(), "policy.pth": pth(Planted(marker))})
    with pytest.raises(InputError, match="not a plain state dict of tensors"):
        sb3_to_onnx(data, env_id=ENV)
    assert not marker.exists()


@pytest.mark.parametrize(
    ("key", "shape"),
    [("features_extractor.cnn.0.weight", (8, 3, 3, 3)), ("actor.mu.weight", (ACT_DIM, 8))],
)
def test_a_policy_that_is_not_an_mlp_policy_is_refused(key: str, shape: tuple[int, ...]) -> None:
    state = mlp_state() | {key: torch.zeros(*shape)}
    data = sb3_zip({"data": settings(), "policy.pth": pth(state)})
    with pytest.raises(InputError, match=f"not an SB3 MlpPolicy: it has the parameter '{key}'"):
        sb3_to_onnx(data, env_id=ENV)


def test_policy_net_layers_must_be_linear_between_activations() -> None:
    state = mlp_state()
    state["mlp_extractor.policy_net.1.weight"] = state.pop("mlp_extractor.policy_net.2.weight")
    state["mlp_extractor.policy_net.1.bias"] = state.pop("mlp_extractor.policy_net.2.bias")
    data = sb3_zip({"data": settings(), "policy.pth": pth(state)})
    with pytest.raises(InputError, match=r"policy_net's layers are \[0, 1\]"):
        sb3_to_onnx(data, env_id=ENV)


def test_a_policy_for_other_sizes_is_refused() -> None:
    data = sb3_zip({"data": settings(), "policy.pth": pth(mlp_state())})
    with pytest.raises(InputError, match=r"not float32 \[N, obs_dim=17\]"):
        sb3_to_onnx(data, env_id="HalfCheetah-v5")


def test_members_over_their_caps_are_refused_before_reading() -> None:
    bomb = sb3_zip({"data": settings(), "policy.pth": b"\0" * (2 * 1024 * 1024)})
    assert len(bomb) < 64 * 1024  # zeros deflate a thousandfold
    with pytest.raises(InputError, match="'policy.pth' inflates to 2097152 bytes, over 1048576"):
        sb3_to_onnx(bomb, env_id=ENV, limits=Sb3Limits(max_policy_bytes=1024 * 1024))
    with pytest.raises(InputError, match="'data' inflates to"):
        sb3_to_onnx(bomb, env_id=ENV, limits=Sb3Limits(max_data_bytes=10))
    with pytest.raises(InputError, match="the SB3 file is over the limit of 100 bytes"):
        sb3_to_onnx(bomb, env_id=ENV, limits=Sb3Limits(max_zip_bytes=100))


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (b"PK not really", "not a readable zip"),
        (sb3_zip({"data": settings()}), "no 'policy.pth'"),
        (sb3_zip({"data": b"[1, 2]", "policy.pth": pth(mlp_state())}), "not a JSON object"),
        (sb3_zip({"data": b"\x80\x04pickle", "policy.pth": pth(mlp_state())}), "is not JSON"),
    ],
)
def test_a_file_that_is_not_an_sb3_save_is_refused(data: bytes, match: str) -> None:
    with pytest.raises(InputError, match=match):
        sb3_to_onnx(data, env_id=ENV)


@pytest.mark.parametrize("how", BREAKS)
def test_a_broken_member_is_an_input_error(how: str) -> None:
    data = sb3_zip({"data": settings(), "policy.pth": pth(mlp_state())})
    with pytest.raises(InputError, match="the SB3 file's 'data' cannot be read"):
        sb3_to_onnx(broken_first_member(data, how), env_id=ENV)


@pytest.mark.parametrize(
    ("tensor", "kind"),
    [
        (lambda w: w.to_sparse(), "sparse"),
        (lambda w: w.to(torch.complex64), "complex64"),
        (lambda w: w.to(torch.int64), "int64"),
    ],
)
def test_weights_that_are_not_dense_real_floats_are_refused(tensor, kind: str) -> None:
    state = mlp_state()
    key = "mlp_extractor.policy_net.0.weight"
    state[key] = tensor(state[key])
    data = sb3_zip({"data": settings(), "policy.pth": pth(state)})
    with pytest.raises(InputError, match=f"{key!r} is .*{kind}.*not a dense tensor of floats"):
        sb3_to_onnx(data, env_id=ENV)


def test_an_unknown_activation_is_refused() -> None:
    with pytest.raises(InputError, match="unknown activation 'gelu'"):
        sb3_to_onnx(b"", env_id=ENV, activation="gelu")
