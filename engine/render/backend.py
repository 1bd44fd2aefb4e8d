"""Headless OpenGL backend for MuJoCo: honour ``MUJOCO_GL``, else EGL, else OSMesa.

MuJoCo's Python bindings pick their GL context class when ``mujoco`` is first imported, from
``MUJOCO_GL``; unset, they pick GLFW, which needs a display. Here the choice is made on first
use instead, and installed into the bindings even if ``mujoco`` was imported earlier (the env
module imports it). Each candidate is probed in a subprocess: PyOpenGL binds its platform
once per process, so a failed EGL attempt would rule out OSMesa in the same process. A
``MUJOCO_GL`` that MuJoCo does not know makes importing ``mujoco`` itself fail: front ends
check it first with :func:`engine.mujoco_gl.check_mujoco_gl`.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import threading
from typing import Any

from engine.mujoco_gl import check_mujoco_gl

#: Backends tried in order when ``MUJOCO_GL`` is unset: EGL is faster, OSMesa more portable.
AUTO_BACKENDS: tuple[str, ...] = ("egl", "osmesa")
DEBIAN_PACKAGES: dict[str, str] = {
    "egl": "libegl1 libegl-mesa0 libgl1-mesa-dri",
    "osmesa": "libosmesa6",
}
_PROBE = "import mujoco; c = mujoco.GLContext(16, 16); c.make_current(); c.free()"
_PROBE_TIMEOUT_S = 60.0

_lock = threading.Lock()
_active: str | None = None


class BackendError(RuntimeError):
    """No usable off-screen OpenGL backend (a machine set-up problem, not bad input)."""


def missing_backend_message(tried: tuple[str, ...] = AUTO_BACKENDS) -> str:
    """The one-line error shown when no backend works, naming the Debian packages."""
    names = " or ".join(b.upper() if b == "egl" else "OSMesa" for b in tried)
    packages = " / ".join(f"'{DEBIAN_PACKAGES[b]}'" for b in tried if b in DEBIAN_PACKAGES)
    return (
        f"no off-screen OpenGL backend for MuJoCo rendering ({names} unavailable): "
        f"install the Debian packages {packages} (apt-get install ...), "
        "or set MUJOCO_GL to a working backend"
    )


def probe(backend: str) -> bool:
    """Whether ``backend`` can create a GL context, tried in a fresh Python process."""
    env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    try:
        done = subprocess.run(
            [sys.executable, "-c", _PROBE],
            env=env,
            capture_output=True,
            timeout=_PROBE_TIMEOUT_S,
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def select_backend() -> str:
    """The backend to use: ``MUJOCO_GL`` when set, else the first of EGL, OSMesa that works.

    Raises:
        InputError: ``MUJOCO_GL`` is set to a value MuJoCo does not know.
        BackendError: ``MUJOCO_GL`` is unset and neither EGL nor OSMesa works.
    """
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested:
        check_mujoco_gl()
        return requested
    for backend in AUTO_BACKENDS:
        if probe(backend):
            return backend
    raise BackendError(missing_backend_message())


def activate() -> str:
    """Select the backend once per process and make MuJoCo's ``Renderer`` use it.

    Safe to call from any thread and many times. Sets ``MUJOCO_GL`` so that child processes
    skip the probe.

    Raises:
        BackendError: no backend works, or the selected one cannot be loaded.
    """
    global _active
    with _lock:
        if _active is None:
            backend = select_backend()
            os.environ["MUJOCO_GL"] = backend
            _install(backend)
            _active = backend
        return _active


def _install(backend: str) -> None:
    """Point MuJoCo's renderer at ``backend``'s context class if its import chose another."""
    if backend not in DEBIAN_PACKAGES:  # glfw, glx, ...: MuJoCo's own choice at import
        return
    os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    try:
        context_cls = importlib.import_module(f"mujoco.{backend}").GLContext
        gl_context: Any = importlib.import_module("mujoco.rendering.classic.gl_context")
    except (ImportError, OSError, AttributeError) as exc:
        raise BackendError(
            f"cannot load the {backend} backend ({exc}); {missing_backend_message((backend,))}"
        ) from exc
    # `Renderer.__init__` reads this module attribute on every construction.
    gl_context.GLContext = context_cls
