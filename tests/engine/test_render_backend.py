"""Choosing the headless OpenGL backend, and the error when there is none."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from engine.errors import InputError
from engine.mujoco_gl import check_mujoco_gl
from engine.render import BackendError, RenderService, backend, renderer, select_backend


@pytest.fixture
def no_mujoco_gl(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    return monkeypatch


@pytest.mark.parametrize(
    ("working", "expected", "tried"),
    [
        ({"egl", "osmesa"}, "egl", ["egl"]),
        ({"osmesa"}, "osmesa", ["egl", "osmesa"]),
    ],
)
def test_egl_first_then_osmesa(
    no_mujoco_gl: pytest.MonkeyPatch, working: set[str], expected: str, tried: list[str]
) -> None:
    calls: list[str] = []
    no_mujoco_gl.setattr(backend, "probe", lambda b: calls.append(b) or b in working)
    assert select_backend() == expected
    assert calls == tried


def test_missing_backend_error_names_the_debian_packages(no_mujoco_gl: pytest.MonkeyPatch) -> None:
    no_mujoco_gl.setattr(backend, "probe", lambda b: False)
    with pytest.raises(BackendError) as info:
        select_backend()
    message = str(info.value)
    assert "\n" not in message
    assert "libegl1 libegl-mesa0 libgl1-mesa-dri" in message and "libosmesa6" in message


def test_mujoco_gl_is_honoured_without_probing(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MUJOCO_GL", "OSMesa ")

    def must_not_probe(name: str) -> bool:
        raise AssertionError(f"probed {name} although MUJOCO_GL is set")

    monkeypatch.setattr(backend, "probe", must_not_probe)
    assert select_backend() == "osmesa"


def test_probe_tells_working_from_broken_backends() -> None:
    assert backend.probe("egl") or backend.probe("osmesa")  # make test installs both
    assert not backend.probe("no-such-backend")


def test_missing_backend_reaches_callers_from_the_render_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def unavailable() -> str:
        raise BackendError(backend.missing_backend_message())

    monkeypatch.setattr(renderer, "activate", unavailable)
    with RenderService() as service:
        for _ in range(2):  # the thread survives and answers again
            with pytest.raises(BackendError, match="libosmesa6"):
                service.render("Hopper-v5", np.zeros(6), np.zeros(6), size=32)


@pytest.mark.parametrize("value", ["egl", "OSMesa ", "glfw", "", "disable"])
def test_values_mujoco_accepts_pass_the_check(value: str) -> None:
    check_mujoco_gl({"MUJOCO_GL": value})


@pytest.mark.parametrize("value", ["foo", "e gl", "osmesa6"])
def test_unknown_mujoco_gl_is_one_clear_input_error(
    value: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(InputError, match=f"invalid MUJOCO_GL={value!r}"):
        check_mujoco_gl({"MUJOCO_GL": value})
    monkeypatch.setenv("MUJOCO_GL", value)
    monkeypatch.setattr(backend, "probe", lambda b: pytest.fail(f"probed {b}"))
    with pytest.raises(InputError, match="egl or osmesa"):
        select_backend()


def _accepted(value: str) -> bool:
    try:
        check_mujoco_gl({"MUJOCO_GL": value})
    except InputError:
        return False
    return True


@pytest.mark.process
@pytest.mark.parametrize(("value", "accepted"), [("foo", False), ("OSMesa", True)])
def test_the_check_agrees_with_mujoco_at_import(value: str, accepted: bool) -> None:
    done = subprocess.run(
        [sys.executable, "-c", "import mujoco"],
        capture_output=True,
        text=True,
        env={**os.environ, "MUJOCO_GL": value},
        timeout=120,
    )
    assert (done.returncode == 0) == accepted, done.stderr
    assert _accepted(value) == accepted
