"""Policies from elsewhere through the API and the CLI: external experiments, uploads of
small Hopper-v5 policies, and Stable-Baselines3 saves made by hand (no SB3 needed)."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
from onnx import ModelProto, TensorProto, helper

from tests.support.onnx_models import (
    ACT_DIM,
    OBS_DIM,
    graph_bytes,
    linear_graph,
    mlp_bytes,
    random_layers,
)
from tests.support.web import ADMIN

#: What an advised policy declares besides its tree (filled in per test).
DECLARED = {"algorithm": "sb3 PPO", "steps": "100000"}


def policy(seed: int = 0, env_id: str | None = "Hopper-v5") -> bytes:
    """A valid Hopper-v5 ONNX policy, different for each ``seed``."""
    return mlp_bytes(env_id=env_id, layers=random_layers(seed=seed))


def with_metadata(data: bytes, **props: str) -> bytes:
    """The model with ``props`` added to its ``metadata_props``."""
    model = ModelProto.FromString(data)
    helper.set_model_props(model, {p.key: p.value for p in model.metadata_props} | props)
    out: bytes = model.SerializeToString()
    return out


def forbidden_op() -> bytes:
    """``action = exp(obs @ w)``: ``Exp`` is not on the allow-list."""
    return linear_graph([helper.make_node("Exp", ["y"], ["z"])], source="z")


def external_data() -> bytes:
    """A policy whose first weight is to be read from ``/etc/passwd``."""
    model = ModelProto.FromString(policy())
    weight = model.graph.initializer[0]
    weight.ClearField("raw_data")
    weight.data_location = TensorProto.EXTERNAL
    entry = weight.external_data.add()
    entry.key, entry.value = "location", "/etc/passwd"
    out: bytes = model.SerializeToString()
    return out


def wrong_sizes() -> bytes:
    """A HalfCheetah-sized graph (17 in, 6 out) that says it is for Hopper-v5."""
    w = np.ones((17, 6), dtype=np.float32)
    return graph_bytes(
        [helper.make_node("MatMul", ["obs", "w"], ["action"])],
        {"w": w},
        inputs=(("obs", TensorProto.FLOAT, ["N", 17]),),
        outputs=(("action", TensorProto.FLOAT, ["N", 6]),),
    )


def obs_norm(obs_dim: int = OBS_DIM) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, mean=np.zeros(obs_dim), var=np.ones(obs_dim), clip=10.0, epsilon=1e-8)
    return buffer.getvalue()


def sb3_zip(hidden: int = 8, extra: dict[str, Any] | None = None, seed: int = 3) -> bytes:
    """A Stable-Baselines3 PPO ``MlpPolicy`` save for Hopper-v5, made by hand: ``data`` (plain
    JSON fields and a pickled one that must stay unread) and ``policy.pth``."""
    import torch

    g = torch.Generator().manual_seed(seed)
    shapes = {
        "mlp_extractor.policy_net.0.weight": (hidden, OBS_DIM),
        "mlp_extractor.policy_net.0.bias": (hidden,),
        "mlp_extractor.policy_net.2.weight": (hidden, hidden),
        "mlp_extractor.policy_net.2.bias": (hidden,),
        "action_net.weight": (ACT_DIM, hidden),
        "action_net.bias": (ACT_DIM,),
        "log_std": (ACT_DIM,),
    }
    state = {k: torch.randn(*s, generator=g) for k, s in shapes.items()} | (extra or {})
    weights = io.BytesIO()
    torch.save(state, weights)
    planted = {":type:": "<class 'x'>", ":serialized:": "80049500"}  # never unpickled
    data = {"num_timesteps": 2048, "seed": seed, "n_envs": 1, "policy_class": planted}
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("data", json.dumps(data))
        archive.writestr("policy.pth", weights.getvalue())
    return buffer.getvalue()


def create_external(client: Any, study_id: int, **body: Any) -> dict[str, Any]:
    """``POST /api/experiments/external`` (teacher ``good`` unless advice is given)."""
    advice = (
        {} if {"teacher", "participant_id", "participant_ids"} & set(body) else {"teacher": "good"}
    )
    response = client.post(
        "/api/experiments/external", json={"study_id": study_id, **advice, **body}, headers=ADMIN
    )
    assert response.status_code == 201, response.text
    return response.json()


def upload(
    client: Any,
    experiment_id: int,
    model: bytes,
    *,
    norm: bytes | None = None,
    headers: dict[str, str] | None = None,
    **fields: Any,
) -> Any:
    """``POST /api/experiments/{id}/agents`` with ``model`` (and ``norm``) and form ``fields``."""
    files: dict[str, Any] = {"model": ("policy.onnx", model, "application/octet-stream")}
    if norm is not None:
        files["obs_norm"] = ("obs_norm.npz", norm, "application/octet-stream")
    data = {k: str(v) for k, v in fields.items() if v is not None}
    return client.post(
        f"/api/experiments/{experiment_id}/agents",
        files=files,
        data=data,
        headers=ADMIN if headers is None else headers,
    )


def stored_files(runs_root: Path) -> list[str]:
    """The names of the stored policies and normalisations (not the judges' rollouts)."""
    folder = runs_root / "policies"
    return sorted(p.name for p in folder.glob("*.*") if p.suffix in (".onnx", ".npz"))
