"""The ONNX graph of an MLP policy's action mean, built from its weights with ``onnx.helper``.

One builder for both converters (an ACV checkpoint, :mod:`engine.policies.export`; an SB3
``MlpPolicy``, :mod:`engine.policies.sb3`): the layers are ``Gemm`` nodes with torch's
``nn.Linear`` weights as they are (``transB=1``), an activation between two layers and none
after the last, which is how both ACV's actor and SB3's ``mlp_extractor.policy_net`` plus
``action_net`` compute the mean. BiPaRS-EM's actor also reads the shaping weight
``z = z_max * tanh(z_mlp(obs))``; its branch computes z from the same input and concatenates
it to the observation, as :class:`engine.rl.networks.Actor` does.

The graph uses opset :data:`EXPORT_OPSET` and only ops that
:func:`engine.policies.onnx_check.check_onnx` allows: what ACV writes passes ACV's own gate.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

from engine.errors import InputError
from engine.policies.onnx_check import ENV_ID_KEY

#: ``(weight, bias)`` of one linear layer in torch's layout: shapes ``(out, in)`` and ``(out,)``.
Layer = tuple[np.ndarray, np.ndarray]
#: Activation names -> ONNX ops (SB3's ``activation_fn``: ``nn.Tanh`` by default, or ``nn.ReLU``).
ACTIVATIONS = {"tanh": "Tanh", "relu": "Relu"}
#: torch.onnx's default for years; onnxruntime runs it from 1.13 on.
EXPORT_OPSET = 17
INPUT_NAME = "obs"
OUTPUT_NAME = "action"


@dataclass(frozen=True, eq=False)
class ZBranch:
    """BiPaRS-EM's shaping weight as the actor's last input: ``z_max * tanh(mlp(obs))``.

    Attributes:
        layers: z_phi's tanh MLP, one output.
        z_max: the bound of z.
    """

    layers: Sequence[Layer]
    z_max: float


@dataclass
class _Graph:
    """Nodes and initializers under unique names."""

    nodes: list[onnx.NodeProto] = field(default_factory=list)
    weights: list[TensorProto] = field(default_factory=list)

    def weight(self, name: str, value: np.ndarray) -> str:
        self.weights.append(numpy_helper.from_array(np.ascontiguousarray(value), name))
        return name

    def node(self, op: str, inputs: list[str], name: str, **attrs: Any) -> str:
        self.nodes.append(helper.make_node(op, inputs, [name], name=name, **attrs))
        return name

    def mlp(self, prefix: str, layers: Sequence[Layer], x: str, activation: str) -> str:
        """``layers`` applied to ``x``, ``activation`` between them; the output's name."""
        for i, (w, b) in enumerate(layers):
            weight = self.weight(f"{prefix}.{i}.weight", w)
            bias = self.weight(f"{prefix}.{i}.bias", b)
            x = self.node("Gemm", [x, weight, bias], f"{prefix}.{i}.gemm", transB=1)
            if i < len(layers) - 1:
                x = self.node(ACTIVATIONS[activation], [x], f"{prefix}.{i}.{activation}")
        return x


def mlp_onnx(
    layers: Sequence[Layer],
    *,
    env_id: str,
    activation: str = "tanh",
    z_branch: ZBranch | None = None,
    metadata: Mapping[str, str] | None = None,
) -> bytes:
    """The serialised ONNX model ``obs [N, obs_dim] -> action [N, act_dim]`` of an MLP mean.

    Args:
        layers: the mean's linear layers, first to last (see :data:`Layer`).
        env_id: written into ``metadata_props`` as ``env_id``.
        activation: a key of :data:`ACTIVATIONS`, between layers.
        z_branch: BiPaRS-EM's z input; the first layer then reads ``obs_dim + 1`` values.
        metadata: more ``metadata_props`` (declared training settings, the producer).

    Raises:
        InputError: an unknown activation, or layers whose shapes do not chain.
    """
    if activation not in ACTIVATIONS:
        raise InputError(f"unknown activation {activation!r}: expected {', '.join(ACTIVATIONS)}")
    layers = _float32(layers)
    obs_dim = _check_chain(layers, "the policy") - (z_branch is not None)
    act_dim = int(layers[-1][0].shape[0])
    graph = _Graph()
    x = INPUT_NAME
    if z_branch is not None:
        x = _with_z(graph, _float32(z_branch.layers), z_branch.z_max, obs_dim)
    mean = graph.mlp("pi", layers, x, activation)
    graph.nodes.append(helper.make_node("Identity", [mean], [OUTPUT_NAME], name="action"))
    model = helper.make_model(
        helper.make_graph(
            graph.nodes,
            "policy_mean",
            [helper.make_tensor_value_info(INPUT_NAME, TensorProto.FLOAT, ["N", obs_dim])],
            [helper.make_tensor_value_info(OUTPUT_NAME, TensorProto.FLOAT, ["N", act_dim])],
            graph.weights,
        ),
        opset_imports=[helper.make_opsetid("", EXPORT_OPSET)],
        producer_name="acv",
    )
    model.ir_version = helper.find_min_ir_version_for(list(model.opset_import))
    helper.set_model_props(model, {**(metadata or {}), ENV_ID_KEY: env_id})
    data: bytes = model.SerializeToString()
    return data


def _with_z(graph: _Graph, layers: list[Layer], z_max: float, obs_dim: int) -> str:
    """``concat(obs, z_max * tanh(z_mlp(obs)))``, as :class:`engine.rl.networks.Actor`."""
    if _check_chain(layers, "z_phi") != obs_dim or layers[-1][0].shape[0] != 1:
        raise InputError(f"z_phi must map the {obs_dim} observation entries to one value")
    raw = graph.mlp("z", layers, INPUT_NAME, "tanh")
    bound = graph.weight("z.max", np.array(z_max, dtype=np.float32))
    z = graph.node("Mul", [graph.node("Tanh", [raw], "z.tanh"), bound], "z")
    return graph.node("Concat", [INPUT_NAME, z], "obs_z", axis=1)


def _float32(layers: Sequence[Layer]) -> list[Layer]:
    return [(np.asarray(w, dtype=np.float32), np.asarray(b, dtype=np.float32)) for w, b in layers]


def _check_chain(layers: Sequence[Layer], what: str) -> int:
    """The first layer's input size, once each layer reads what the one before writes."""
    if not layers:
        raise InputError(f"{what} has no layers")
    written = None  # the size the layer before writes
    for i, (w, b) in enumerate(layers):
        if w.ndim != 2 or b.shape != (w.shape[0],) or written not in (None, w.shape[1]):
            raise InputError(
                f"{what}'s layer {i} has weight {w.shape} and bias {b.shape}: the shapes do "
                "not chain"
            )
        written = w.shape[0]
    return int(layers[0][0].shape[1])
