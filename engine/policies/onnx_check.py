"""The gate of every policy from elsewhere: an ONNX model, checked from its bytes.

An imported policy is stored and run as ONNX only (issue 44 §2). A model passes when it is a
small feed-forward network for the experiment's env and nothing else; each rule is refused
with an :class:`~engine.errors.InputError` naming it (the CLI exits 2, the API answers 4xx):

- at most :attr:`OnnxLimits.max_bytes` bytes, checked before parsing;
- parsed from the bytes (protobuf, no file paths): a corrupt file is refused;
- the graph rules of :mod:`engine.policies.onnx_rules`: no external data, no functions or
  subgraphs, allow-listed operators of the default domain within an opset range, at most
  :attr:`OnnxLimits.max_nodes` nodes and :attr:`OnnxLimits.max_initializer_bytes` of weights;
- the env id from the model's ``metadata_props`` (``env_id``) or given with the upload
  (``declared_env_id``), equal where both are given, and equal to the experiment's. Shapes
  alone do not tell envs apart: Humanoid-v5 and HumanoidStandup-v5 share both;
- one float32 input ``[N, obs_dim]`` and one float32 output ``[N, act_dim]`` (``N`` dynamic
  or 1: the judges act one observation at a time);
- and ONNX's own checker, with full shape inference (it also catches an output that is not
  the shape the model declares).

The rules bound the file, not the work of running it: a chain of ``Concat`` can grow a tensor
geometrically. That is what the judging child's memory and time limits are for
(:mod:`engine.policies.sandbox`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import cast

import onnx
from onnx import GraphProto, ModelProto, TensorProto, ValueInfoProto

from engine.errors import InputError
from engine.policies.onnx_rules import check_graph

MiB = 1024 * 1024
#: The ``metadata_props`` key that names the env the policy acts in.
ENV_ID_KEY = "env_id"


@dataclass(frozen=True)
class OnnxLimits:
    """The sizes a model may have.

    Attributes:
        max_bytes: the file, before it is parsed (weights, plus the graph and metadata).
        max_initializer_bytes: all weights (initializers and ``Constant`` values) together.
        max_nodes: the graph's nodes.
    """

    max_bytes: int = 72 * MiB
    max_initializer_bytes: int = 64 * MiB
    max_nodes: int = 10_000


@dataclass(frozen=True)
class CheckedOnnx:
    """A model that passed :func:`check_onnx`: only these are run.

    Attributes:
        data: the file's bytes, as uploaded (what is stored and hashed).
        env_id: the env the policy acts in (the experiment's).
        obs_dim: the input's size per row.
        act_dim: the output's size per row.
        input_name: the graph's one input.
        output_name: the graph's one output.
        opset: the default domain's opset.
        metadata: the model's ``metadata_props`` (declared training settings, the producer).
    """

    data: bytes = field(repr=False)
    env_id: str
    obs_dim: int
    act_dim: int
    input_name: str
    output_name: str
    opset: int
    metadata: dict[str, str] = field(default_factory=dict, hash=False)

    @property
    def digest(self) -> str:
        """SHA-256 of the file, hex."""
        return hashlib.sha256(self.data).hexdigest()


def check_onnx(
    data: bytes,
    *,
    env_id: str,
    obs_dim: int,
    act_dim: int,
    declared_env_id: str | None = None,
    limits: OnnxLimits = OnnxLimits(),
) -> CheckedOnnx:
    """Check an uploaded ONNX model against every rule of the module docstring.

    Args:
        data: the file's bytes.
        env_id: the experiment's env; the policy's must equal it.
        obs_dim: the env's observation size (:func:`engine.envs.env_dims`).
        act_dim: the env's action size.
        declared_env_id: the env id given with the upload (a form field, a CLI option), for a
            model without ``env_id`` in its metadata; None when not given.
        limits: the sizes allowed.

    Raises:
        InputError: a rule is broken; the message names it.
    """
    if len(data) > limits.max_bytes:
        raise InputError(
            f"the ONNX file is {len(data)} bytes, over the limit of {limits.max_bytes} bytes"
        )
    model = _parse(data)
    opset = check_graph(
        model, max_nodes=limits.max_nodes, max_weight_bytes=limits.max_initializer_bytes
    )
    policy_env = _check_env_id(model, env_id, declared_env_id)
    input_name, output_name = _check_io(model.graph, obs_dim, act_dim)
    _run_checker(model)
    metadata = {p.key: p.value for p in model.metadata_props}
    return CheckedOnnx(data, policy_env, obs_dim, act_dim, input_name, output_name, opset, metadata)


def _parse(data: bytes) -> ModelProto:
    """The model in ``data``; protobuf parses some garbage (the empty file is an empty
    message), so a model without an IR version or a graph is refused too."""
    try:
        model = cast(ModelProto, ModelProto.FromString(data))
    except Exception as exc:  # protobuf's DecodeError (untyped), or a recursion limit
        raise InputError(f"not an ONNX model: the file does not parse ({exc})") from exc
    if model.ir_version < 1 or not model.HasField("graph"):
        raise InputError("not an ONNX model: no IR version or no graph")
    return model


def _check_env_id(model: ModelProto, env_id: str, declared: str | None) -> str:
    """The policy's env: the metadata's or the declared one (equal where both are given)."""
    meta = {p.key: p.value for p in model.metadata_props}.get(ENV_ID_KEY) or None
    if meta is None and not declared:
        raise InputError(
            f"no env id: the model's metadata_props has no {ENV_ID_KEY!r} and none was given "
            "with the upload"
        )
    if meta is not None and declared and meta != declared:
        raise InputError(
            f"the model's metadata says env_id {meta!r}, but {declared!r} was given with the upload"
        )
    policy_env = meta or declared
    if policy_env != env_id:
        raise InputError(f"the policy is for {policy_env}, but the experiment is on {env_id}")
    return env_id


def _check_io(graph: GraphProto, obs_dim: int, act_dim: int) -> tuple[str, str]:
    weights = {t.name for t in graph.initializer}
    inputs = [i for i in graph.input if i.name not in weights]
    if len(inputs) != 1 or len(graph.output) != 1:
        raise InputError(
            f"the model has {len(inputs)} inputs and {len(graph.output)} outputs: a policy has "
            "one input (the observation) and one output (the action)"
        )
    _check_matrix(inputs[0], "input", "obs_dim", obs_dim)
    _check_matrix(graph.output[0], "output", "act_dim", act_dim)
    return inputs[0].name, graph.output[0].name


def _check_matrix(value: ValueInfoProto, role: str, size_name: str, size: int) -> None:
    """``value`` is a float32 tensor ``[N, size]`` with ``N`` dynamic or 1."""
    want = f"float32 [N, {size_name}={size}]"
    tensor = value.type.tensor_type
    if not value.type.HasField("tensor_type") or not tensor.HasField("shape"):
        raise InputError(f"the model's {role} {value.name!r} is not a tensor of known rank: {want}")
    if tensor.elem_type != TensorProto.FLOAT:
        raise InputError(
            f"the model's {role} {value.name!r} is {_dtype_name(tensor.elem_type)}, not {want}"
        )
    dims = [d.dim_value if d.HasField("dim_value") else None for d in tensor.shape.dim]
    if len(dims) != 2 or dims[1] != size:
        shown = ", ".join("?" if d is None else str(d) for d in dims)
        raise InputError(f"the model's {role} {value.name!r} is [{shown}], not {want}")
    if dims[0] not in (None, 1):
        raise InputError(
            f"the model's {role} {value.name!r} has a fixed batch of {dims[0]}: the batch "
            "dimension must be dynamic or 1"
        )


def _run_checker(model: ModelProto) -> None:
    try:
        onnx.checker.check_model(model, full_check=True)
    except Exception as exc:  # ValidationError, InferenceError, or another of its C++ layer's
        text = str(exc).strip()
        first = text.splitlines()[0] if text else type(exc).__name__
        raise InputError(f"the ONNX checker refused the model: {first}") from exc


def _dtype_name(elem_type: int) -> str:
    """``DOUBLE`` for ``TensorProto.DOUBLE``; the number for a type ONNX does not know."""
    try:
        return str(TensorProto.DataType.Name(elem_type))
    except ValueError:
        return f"element type {elem_type}"
