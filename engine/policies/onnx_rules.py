"""The graph rules of :func:`engine.policies.onnx_check.check_onnx`: what a policy's ONNX graph
may contain. Each broken rule raises an :class:`~engine.errors.InputError` naming it.

- no tensor with external data: its weights would be read from a path on the server;
- no model-local functions and no training graphs: one plain inference graph is all a policy
  needs;
- the default domain's opset within :data:`OPSETS`;
- at most so many nodes and bytes of weights (the caller's limits);
- operators of the default domain only, from :data:`ALLOWED_OPS` (no ``Loop``, ``Scan``,
  ``If``, no ``Shape``, ``Size`` or ``ConstantOfShape``: no control flow, no shape computed
  from the data), no subgraph in any node's attributes (where control flow lives), and the
  shape or axes input of :data:`SHAPE_INPUT_OPS` a constant.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import onnx
from onnx import AttributeProto, GraphProto, ModelProto, TensorProto

from engine.errors import InputError

#: Default-domain opsets accepted, both ends included. From 13 on, ``Squeeze`` and
#: ``Unsqueeze`` take their axes as an input, so the constant-input rule reads one form (and
#: ``torch.onnx`` exports 17 or 18 by default); 21 is the newest that onnxruntime 1.20, the
#: oldest this project accepts, runs.
OPSETS = (13, 21)
_PRODUCTS = ("Gemm", "MatMul")
_ARITHMETIC = ("Add", "Sub", "Mul", "Div", "Neg")
_ACTIVATIONS = ("Relu", "Tanh", "Sigmoid", "Elu", "LeakyRelu", "Softplus", "Clip")
_PLUMBING = ("Concat", "Flatten", "Reshape", "Squeeze", "Unsqueeze", "Identity", "Constant")
#: The operators of a feed-forward policy: matrix products, elementwise arithmetic, the usual
#: activations, and the reshaping a converter emits around them.
ALLOWED_OPS = frozenset(_PRODUCTS + _ARITHMETIC + _ACTIVATIONS + _PLUMBING)
#: Allowed operators whose second input is a shape or axes: it must be a constant, so that no
#: shape is computed from the observation.
SHAPE_INPUT_OPS = frozenset({"Reshape", "Squeeze", "Unsqueeze"})
#: The default ONNX domain's two spellings.
DEFAULT_DOMAINS = ("", "ai.onnx")


def check_graph(model: ModelProto, *, max_nodes: int, max_weight_bytes: int) -> int:
    """Apply the module's rules, in its order; the default domain's opset.

    Args:
        model: the parsed model.
        max_nodes: the most nodes allowed.
        max_weight_bytes: the most bytes of weights (initializers and constants) allowed.

    Raises:
        InputError: a rule is broken.
    """
    _check_no_external_data(model.graph)
    _check_structure(model)
    opset = _check_opset(model)
    _check_sizes(model.graph, max_nodes, max_weight_bytes)
    _check_ops(model.graph)
    return opset


def _check_no_external_data(graph: GraphProto) -> None:
    for tensor in _tensors(graph):
        if tensor.data_location == TensorProto.EXTERNAL or len(tensor.external_data):
            raise InputError(
                f"tensor {tensor.name!r} has external data: all weights must be inside the file"
            )


def _tensors(graph: GraphProto) -> Iterator[TensorProto]:
    """Every tensor of ``graph`` and its subgraphs: initializers, sparse ones, attributes."""
    yield from graph.initializer
    for sparse in graph.sparse_initializer:
        yield from (sparse.values, sparse.indices)
    for node in graph.node:
        for attr in node.attribute:
            yield from _attribute_tensors(attr)


def _attribute_tensors(attr: AttributeProto) -> Iterator[TensorProto]:
    if attr.HasField("t"):
        yield attr.t
    yield from attr.tensors
    if attr.HasField("sparse_tensor"):
        yield from (attr.sparse_tensor.values, attr.sparse_tensor.indices)
    for sparse in attr.sparse_tensors:
        yield from (sparse.values, sparse.indices)
    if attr.HasField("g"):
        yield from _tensors(attr.g)
    for graph in attr.graphs:
        yield from _tensors(graph)


def _check_structure(model: ModelProto) -> None:
    if len(model.functions):
        raise InputError("the model defines functions: only a plain graph of operators is run")
    if len(model.training_info):
        raise InputError("the model carries training graphs: only an inference graph is run")


def _check_opset(model: ModelProto) -> int:
    versions = [int(o.version) for o in model.opset_import if o.domain in DEFAULT_DOMAINS]
    if not versions:
        raise InputError("the model imports no opset of the default ONNX domain")
    low, high = OPSETS
    if not all(low <= v <= high for v in versions):
        raise InputError(f"the model's opset is {max(versions)}: accepted are {low} to {high}")
    return max(versions)


def _check_sizes(graph: GraphProto, max_nodes: int, max_weight_bytes: int) -> None:
    if len(graph.node) > max_nodes:
        raise InputError(f"the model has {len(graph.node)} nodes, over the limit of {max_nodes}")
    weights = sum(_tensor_bytes(t) for t in _tensors(graph))
    if weights > max_weight_bytes:
        raise InputError(
            f"the model's weights take {weights} bytes, over the limit of {max_weight_bytes} bytes"
        )


def _tensor_bytes(tensor: TensorProto) -> int:
    """What a tensor holds or claims to hold, whichever is more (dims can claim more than the
    data, and the runtime may allocate what they claim)."""
    try:
        itemsize = int(onnx.helper.tensor_dtype_to_np_dtype(tensor.data_type).itemsize)
    except (KeyError, ValueError, TypeError):
        itemsize = 8
    declared = int(math.prod(tensor.dims)) * itemsize
    stored = (
        len(tensor.raw_data)
        + 4 * (len(tensor.float_data) + len(tensor.int32_data))
        + 8 * (len(tensor.int64_data) + len(tensor.double_data) + len(tensor.uint64_data))
        + sum(len(s) for s in tensor.string_data)
    )
    return max(declared, stored)


def _check_ops(graph: GraphProto) -> None:
    constants = {t.name for t in graph.initializer} | {
        out for node in graph.node if node.op_type == "Constant" for out in node.output
    }
    for node in graph.node:
        where = f"node {node.name!r}" if node.name else "a node"
        if node.domain not in DEFAULT_DOMAINS:
            raise InputError(
                f"{where} uses op {node.op_type!r} of the custom domain {node.domain!r}: "
                "only the default ONNX domain is allowed"
            )
        if node.op_type not in ALLOWED_OPS:
            raise InputError(
                f"{where} uses op {node.op_type!r}, which is not allowed; allowed are "
                f"{', '.join(sorted(ALLOWED_OPS))}"
            )
        if any(a.type in (AttributeProto.GRAPH, AttributeProto.GRAPHS) for a in node.attribute):
            raise InputError(f"{where} ({node.op_type}) has a subgraph: none is allowed")
        shape = node.input[1] if node.op_type in SHAPE_INPUT_OPS and len(node.input) > 1 else ""
        if shape and shape not in constants:
            raise InputError(
                f"{where} ({node.op_type}) takes its shape from {shape!r}, which is not a "
                "constant: shapes must be initializers or Constant outputs"
            )
