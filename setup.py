"""The one build step that ``pyproject.toml`` cannot say: the repository keeps
``templates/``, ``static/`` and ``migrations/`` at its root (the design card's layout), and a
wheel carries them inside the ``app`` package, where :mod:`app.core.resources` finds them.
An editable install finds them in the checkout and copies nothing.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

#: The folders copied from the repository root into ``app/`` (``app.core.resources.FOLDERS``).
FOLDERS = ("templates", "static", "migrations")


class BuildPyWithResources(build_py):
    """``build_py``, then the resource folders into the built ``app`` package."""

    def run(self) -> None:
        super().run()
        if self.editable_mode:
            return
        for name in FOLDERS:
            target = Path(self.build_lib, "app", name)
            shutil.rmtree(target, ignore_errors=True)  # nothing left from an earlier build
            shutil.copytree(name, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": BuildPyWithResources})
