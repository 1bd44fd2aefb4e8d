"""Imported policies are judged in a child process with memory and time limits (issue 44 §2):
a child past its time is killed, one past its memory fails, a policy that fails says why, and
each comes back as an :class:`InputError` naming the reason."""

from __future__ import annotations

import time

import numpy as np
import pytest
from onnx import helper

from engine.errors import InputError
from engine.policies.onnx_check import check_onnx
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.policies.sandbox import ChildLimits, VisitJob, run_in_child
from engine.rl.behaviour import RolloutOptions, visited_states
from tests.support.onnx_models import ACT_DIM, ENV, OBS_DIM, graph_bytes, mlp_bytes

pytestmark = pytest.mark.process


def imported(data: bytes) -> ImportedPolicy:
    return ImportedPolicy(check_onnx(data, env_id=ENV, obs_dim=OBS_DIM, act_dim=ACT_DIM))


def doubling(times: int) -> bytes:
    """A model that passes the gate and doubles the observation ``times`` times (a Concat
    chain), then reads rows of 11: ``times`` = 26 asks for 2.8 GB."""
    nodes = [helper.make_node("Concat", ["obs", "obs"], ["x0"], axis=1)]
    for i in range(1, times):
        nodes.append(helper.make_node("Concat", [f"x{i - 1}", f"x{i - 1}"], [f"x{i}"], axis=1))
    nodes.append(helper.make_node("Reshape", [f"x{times - 1}", "shape"], ["rows"]))
    nodes.append(helper.make_node("MatMul", ["rows", "w"], ["action"]))
    weights = {
        "shape": np.array([-1, OBS_DIM], np.int64),
        "w": np.ones((OBS_DIM, ACT_DIM), np.float32),
    }
    return graph_bytes(nodes, weights)


def test_the_child_returns_what_the_rollouts_give_in_process() -> None:
    """Hopper under a random network falls within the burn-in: lower it to see states."""
    policy, options = imported(mlp_bytes()), RolloutOptions(episodes=2, burn_in=5)
    got = run_in_child(VisitJob(policy, options))
    assert got.shape[0] > 0
    np.testing.assert_array_equal(got, visited_states(OnnxPolicy(policy), ENV, options))


def test_a_child_past_its_time_is_killed() -> None:
    endless = RolloutOptions(episodes=10**9, max_steps=10**9)
    started = time.monotonic()
    with pytest.raises(
        InputError, match="longer than its limit of 3 s: the child process was killed"
    ):
        run_in_child(VisitJob(imported(mlp_bytes()), endless), ChildLimits(seconds=3))
    assert time.monotonic() - started < 10


def test_a_child_past_its_memory_fails_with_the_reason() -> None:
    limits = ChildLimits(memory_bytes=256 * 1024 * 1024)
    with pytest.raises(InputError, match=r"ran out of its memory limit \(256 MiB\)"):
        run_in_child(VisitJob(imported(doubling(26)), RolloutOptions(episodes=1)), limits)


def test_a_policy_that_fails_in_the_child_says_why() -> None:
    """Three doublings fit in memory but give 8 rows per observation, not 1."""
    with pytest.raises(InputError, match=r"the policy computed \(8, 3\), not float32 \(1, 3\)"):
        run_in_child(VisitJob(imported(doubling(3)), RolloutOptions(episodes=1)))
