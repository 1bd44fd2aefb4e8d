"""Checking ``MUJOCO_GL`` before anything imports :mod:`mujoco`.

MuJoCo's bindings read ``MUJOCO_GL`` when they are first imported and raise a bare
``RuntimeError`` for a value they do not know, so a typo would give a traceback for every
command. This module imports nothing from MuJoCo: front ends call :func:`check_mujoco_gl`
before they import the modules that do. The accepted values mirror
``mujoco/rendering/classic/gl_context.py`` (case and surrounding spaces ignored, as there).
"""

from __future__ import annotations

import os
import platform
from collections.abc import Mapping

from engine.errors import InputError

_OFF = ("disable", "disabled", "off", "false", "0")
_ON = ("enable", "enabled", "on", "true", "1", "glfw", "")
_PLATFORM = {"Linux": ("glx", "egl", "osmesa"), "Windows": ("wgl",), "Darwin": ("cgl",)}


def valid_mujoco_gl() -> tuple[str, ...]:
    """The ``MUJOCO_GL`` values MuJoCo accepts on this platform."""
    return _OFF + _ON + _PLATFORM.get(platform.system(), ())


def check_mujoco_gl(environ: Mapping[str, str] | None = None) -> None:
    """Raise :class:`InputError` if ``MUJOCO_GL`` is set to a value MuJoCo would refuse.

    Args:
        environ: the environment to read; ``os.environ`` by default.
    """
    env = os.environ if environ is None else environ
    value = env.get("MUJOCO_GL", "")
    if value.lower().strip() not in valid_mujoco_gl():
        named = ", ".join(v for v in _PLATFORM.get(platform.system(), ()) + ("glfw",))
        raise InputError(
            f"invalid MUJOCO_GL={value!r}: use one of {named} (egl or osmesa "
            "for headless rendering), or unset it to pick one automatically"
        )
