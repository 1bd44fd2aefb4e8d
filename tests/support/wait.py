"""Waiting for a state another thread or process brings about, never for a fixed time."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import pytest

T = TypeVar("T")


def wait_for(
    probe: Callable[[], T],
    until: Callable[[T], object] = bool,
    *,
    what: str,
    timeout_s: float = 60.0,
    every_s: float = 0.1,
) -> T:
    """Call ``probe`` until ``until`` holds for its value; return that value.

    Args:
        probe: reads the state (may raise to stop waiting, e.g. when a server exited).
        until: the condition on the value (default: the value is truthy).
        what: what is awaited, for the failure message.
        timeout_s: how long to wait before failing the test (with the last value seen).
        every_s: the pause between two probes.
    """
    deadline = time.monotonic() + timeout_s
    while not until(value := probe()):
        if time.monotonic() >= deadline:
            pytest.fail(
                f"waited {timeout_s:g} s for {what}; last seen: {value!r}"[:3000], pytrace=False
            )
        time.sleep(every_s)
    return value
