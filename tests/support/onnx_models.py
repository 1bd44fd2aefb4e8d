"""Small ONNX models for the import path's tests: a Hopper-v5-sized MLP, and hand-made graphs
that each break one rule of :func:`engine.policies.onnx_check.check_onnx`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from onnx import ModelProto, NodeProto, TensorProto, helper, numpy_helper

from engine.policies.onnx_build import Layer, mlp_onnx

ENV, OBS_DIM, ACT_DIM = "Hopper-v5", 11, 3


def random_layers(
    sizes: Sequence[int] = (OBS_DIM, 16, 16, ACT_DIM), seed: int = 0, scale: float = 0.5
) -> list[Layer]:
    """Random ``(weight (out, in), bias)`` layers of the given widths, float32."""
    rng = np.random.default_rng(seed)
    return [
        (
            (scale * rng.standard_normal((n_out, n_in))).astype(np.float32),
            (scale * rng.standard_normal(n_out)).astype(np.float32),
        )
        for n_in, n_out in zip(sizes[:-1], sizes[1:], strict=True)
    ]


def numpy_mean(layers: Sequence[Layer], x: np.ndarray, activation: str = "tanh") -> np.ndarray:
    """The MLP's output in float64 numpy: the reference the ONNX policy is compared with."""
    act = {"tanh": np.tanh, "relu": lambda v: np.maximum(v, 0.0)}[activation]
    h = np.asarray(x, dtype=np.float64)
    for i, (w, b) in enumerate(layers):
        h = h @ w.T.astype(np.float64) + b
        if i < len(layers) - 1:
            h = act(h)
    return h


def mlp_bytes(
    env_id: str | None = ENV, activation: str = "tanh", layers: Sequence[Layer] | None = None
) -> bytes:
    """A valid Hopper-v5 policy (``env_id`` None: no env id in its metadata)."""
    layers = random_layers() if layers is None else layers
    data = mlp_onnx(layers, env_id=env_id or "unset", activation=activation)
    if env_id is None:
        model = ModelProto.FromString(data)
        del model.metadata_props[:]
        data = model.SerializeToString()
    return data


def graph_bytes(
    nodes: Sequence[NodeProto],
    weights: dict[str, np.ndarray] | None = None,
    *,
    inputs: Sequence[tuple[str, int, list[object]]] = (("obs", TensorProto.FLOAT, ["N", OBS_DIM]),),
    outputs: Sequence[tuple[str, int, list[object]]] = (
        ("action", TensorProto.FLOAT, ["N", ACT_DIM]),
    ),
    opset: int = 17,
    env_id: str | None = ENV,
) -> bytes:
    """A hand-made model: ``nodes`` over ``weights``, with the given inputs and outputs."""
    model = helper.make_model(
        helper.make_graph(
            list(nodes),
            "test",
            [helper.make_tensor_value_info(n, t, s) for n, t, s in inputs],
            [helper.make_tensor_value_info(n, t, s) for n, t, s in outputs],
            [numpy_helper.from_array(v, k) for k, v in (weights or {}).items()],
        ),
        opset_imports=[helper.make_opsetid("", opset)],
    )
    model.ir_version = 8
    if env_id is not None:
        helper.set_model_props(model, {"env_id": env_id})
    data: bytes = model.SerializeToString()
    return data


def linear_graph(extra: Sequence[NodeProto] = (), source: str = "y") -> bytes:
    """``action = obs @ w`` (w of shape (11, 3)) followed by ``extra`` nodes, whose last output
    (``source``) is renamed ``action``."""
    w = np.ones((OBS_DIM, ACT_DIM), dtype=np.float32)
    nodes = [helper.make_node("MatMul", ["obs", "w"], ["y"]), *extra]
    nodes.append(helper.make_node("Identity", [source], ["action"]))
    return graph_bytes(nodes, {"w": w})
