"""The gate of imported policies (issue 44 §2): every rule of
:func:`engine.policies.onnx_check.check_onnx` refuses a model that breaks it, with a message
naming the rule, and lets a plain MLP through."""

from __future__ import annotations

import numpy as np
import pytest
from onnx import ModelProto, TensorProto, helper

from engine.errors import InputError
from engine.policies.onnx_check import CheckedOnnx, OnnxLimits, check_onnx
from tests.support.onnx_models import (
    ACT_DIM,
    ENV,
    OBS_DIM,
    graph_bytes,
    linear_graph,
    mlp_bytes,
)


def check(data: bytes, **kwargs: object) -> CheckedOnnx:
    """:func:`check_onnx` for the Hopper-v5 experiment."""
    options: dict[str, object] = {"env_id": ENV, "obs_dim": OBS_DIM, "act_dim": ACT_DIM}
    return check_onnx(data, **(options | kwargs))  # type: ignore[arg-type]


def refused(data: bytes, match: str, **kwargs: object) -> None:
    with pytest.raises(InputError, match=match):
        check(data, **kwargs)


def test_a_plain_mlp_passes() -> None:
    data = mlp_bytes()
    checked = check(data)
    assert (checked.env_id, checked.obs_dim, checked.act_dim) == (ENV, OBS_DIM, ACT_DIM)
    assert (checked.input_name, checked.output_name, checked.opset) == ("obs", "action", 17)
    assert checked.metadata["env_id"] == ENV and checked.data == data
    assert len(checked.digest) == 64


@pytest.mark.parametrize("data", [b"\x00\xffgarbage", b"", b"not an onnx file"])
def test_a_corrupt_file_is_refused(data: bytes) -> None:
    refused(data, "not an ONNX model")


def test_a_truncated_file_is_refused() -> None:
    data = mlp_bytes()
    refused(data[: len(data) // 2], "not an ONNX model")


def test_a_file_over_the_byte_cap_is_refused_before_parsing() -> None:
    data = mlp_bytes()
    refused(
        data, f"is {len(data)} bytes, over the limit of 1000", limits=OnnxLimits(max_bytes=1000)
    )


def test_external_data_is_refused() -> None:
    model = ModelProto.FromString(mlp_bytes())
    weight = model.graph.initializer[0]
    weight.ClearField("raw_data")
    weight.data_location = TensorProto.EXTERNAL
    entry = weight.external_data.add()
    entry.key, entry.value = "location", "/etc/passwd"
    refused(model.SerializeToString(), "has external data")


@pytest.mark.parametrize("op", ["Shape", "Size", "ConstantOfShape", "Exp"])
def test_an_op_outside_the_allow_list_is_refused(op: str) -> None:
    nodes = [helper.make_node(op, ["y"], ["z"])]
    refused(linear_graph(nodes, "z"), f"uses op '{op}', which is not allowed")


def test_control_flow_is_refused() -> None:
    body = helper.make_graph(
        [helper.make_node("Identity", ["c"], ["c_out"])],
        "body",
        [
            helper.make_tensor_value_info("i", TensorProto.INT64, []),
            helper.make_tensor_value_info("cond", TensorProto.BOOL, []),
            helper.make_tensor_value_info("c", TensorProto.FLOAT, None),
        ],
        [
            helper.make_tensor_value_info("cond", TensorProto.BOOL, []),
            helper.make_tensor_value_info("c_out", TensorProto.FLOAT, None),
        ],
    )
    loop = helper.make_node("Loop", ["", "", "y"], ["z"], body=body)
    refused(linear_graph([loop], "z"), "uses op 'Loop', which is not allowed")


def test_a_subgraph_on_an_allowed_op_is_refused() -> None:
    body = helper.make_graph([], "stray", [], [])
    refused(linear_graph([helper.make_node("Relu", ["y"], ["z"], g=body)], "z"), "subgraph")


def test_a_custom_domain_is_refused() -> None:
    node = helper.make_node("Relu", ["y"], ["z"], domain="com.example")
    refused(linear_graph([node], "z"), "custom domain 'com.example'")


def test_functions_are_refused() -> None:
    model = ModelProto.FromString(mlp_bytes())
    model.functions.add().name = "hidden"
    refused(model.SerializeToString(), "defines functions")


def test_a_reshape_needs_a_constant_shape() -> None:
    shape = np.array([-1, ACT_DIM], dtype=np.int64)
    constant = [helper.make_node("Reshape", ["y", "shape"], ["z"])]
    computed = [
        helper.make_node("Identity", ["shape"], ["shape2"]),
        helper.make_node("Reshape", ["y", "shape2"], ["z"]),
    ]
    for nodes, ok in ((constant, True), (computed, False)):
        data = graph_bytes(
            [helper.make_node("MatMul", ["obs", "w"], ["y"]), *nodes],
            {"w": np.ones((OBS_DIM, ACT_DIM), np.float32), "shape": shape},
            outputs=(("z", TensorProto.FLOAT, ["N", ACT_DIM]),),
        )
        if ok:
            check(data)
        else:
            refused(data, "takes its shape from 'shape2', which is not a constant")


@pytest.mark.parametrize("opset", [11, 22])
def test_an_opset_outside_the_range_is_refused(opset: int) -> None:
    data = graph_bytes([helper.make_node("Relu", ["obs"], ["action"])], opset=opset)
    refused(data, f"opset is {opset}: accepted are 13 to 21")


def test_too_many_nodes_are_refused() -> None:
    refused(mlp_bytes(), "nodes, over the limit of 3", limits=OnnxLimits(max_nodes=3))


def test_too_many_weights_are_refused() -> None:
    limits = OnnxLimits(max_initializer_bytes=100)
    refused(mlp_bytes(), "weights take .* bytes, over the limit of 100", limits=limits)


def test_weights_that_claim_more_than_they_hold_count_what_they_claim() -> None:
    model = ModelProto.FromString(mlp_bytes())
    model.graph.initializer[0].dims[:] = [10**9, 10**3]
    refused(model.SerializeToString(), "over the limit of")


def test_a_missing_env_id_is_refused_unless_given_with_the_upload() -> None:
    data = mlp_bytes(env_id=None)
    refused(data, "no env id")
    assert check(data, declared_env_id=ENV).env_id == ENV


def test_an_env_id_that_differs_from_the_upload_is_refused() -> None:
    refused(
        mlp_bytes(),
        "metadata says env_id 'Hopper-v5', but 'Walker2d-v5'",
        declared_env_id="Walker2d-v5",
    )


def test_a_wrong_env_id_is_refused() -> None:
    """Shapes alone do not tell envs apart (Humanoid-v5 and HumanoidStandup-v5 share both)."""
    refused(
        mlp_bytes(),
        "the policy is for Hopper-v5, but the experiment is on Walker2d-v5",
        env_id="Walker2d-v5",
    )
    refused(
        mlp_bytes(env_id=None),
        "the policy is for Swimmer-v5",
        declared_env_id="Swimmer-v5",
    )


def test_wrong_observation_or_action_sizes_are_refused() -> None:
    refused(mlp_bytes(), r"input 'obs' is \[\?, 11\], not float32 \[N, obs_dim=17\]", obs_dim=17)
    refused(mlp_bytes(), r"output 'action' is \[\?, 3\], not float32 \[N, act_dim=6\]", act_dim=6)


def test_the_input_must_be_float32() -> None:
    data = graph_bytes(
        [helper.make_node("Relu", ["obs"], ["action"])],
        inputs=(("obs", TensorProto.DOUBLE, ["N", OBS_DIM]),),
        outputs=(("action", TensorProto.DOUBLE, ["N", OBS_DIM]),),
    )
    refused(data, "input 'obs' is DOUBLE, not float32", act_dim=OBS_DIM)


def test_one_input_and_one_output() -> None:
    two_in = graph_bytes(
        [helper.make_node("Add", ["obs", "more"], ["action"])],
        inputs=(("obs", TensorProto.FLOAT, ["N", 3]), ("more", TensorProto.FLOAT, ["N", 3])),
    )
    refused(two_in, "2 inputs and 1 outputs", obs_dim=3)
    two_out = graph_bytes(
        [helper.make_node("Relu", ["obs"], ["a"]), helper.make_node("Tanh", ["obs"], ["b"])],
        outputs=(("a", TensorProto.FLOAT, ["N", 11]), ("b", TensorProto.FLOAT, ["N", 11])),
    )
    refused(two_out, "1 inputs and 2 outputs", act_dim=11)


def test_a_fixed_batch_above_one_is_refused() -> None:
    data = graph_bytes(
        [helper.make_node("Relu", ["obs"], ["action"])],
        inputs=(("obs", TensorProto.FLOAT, [8, 3]),),
        outputs=(("action", TensorProto.FLOAT, [8, 3]),),
    )
    refused(data, "fixed batch of 8", obs_dim=3, act_dim=3)


def test_the_onnx_checker_catches_a_declared_output_the_graph_does_not_compute() -> None:
    data = graph_bytes(
        [helper.make_node("MatMul", ["obs", "w"], ["action"])],
        {"w": np.ones((OBS_DIM, 4), np.float32)},
    )
    refused(data, "the ONNX checker refused the model")
