"""Where the app's files that are not Python code live: its templates, static files and
database migrations. Every lookup of them goes through here.

A wheel carries them inside the ``app`` package (``app/templates``, ``app/static``,
``app/migrations``; ``setup.py`` copies them there when it builds one). A checkout, and the
editable install made from it (``make``, the Docker image), keeps them at the repository
root beside ``app/``, as the design card draws the repository. Both are found from the
``app`` package through :mod:`importlib.resources`: inside it first, then beside it.
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path
from typing import Literal

#: The folders, by the name they have both in a checkout and in the wheel.
Folder = Literal["templates", "static", "migrations"]
FOLDERS: tuple[Folder, ...] = ("templates", "static", "migrations")


def package_dir() -> Path:
    """The ``app`` package's folder.

    Raises:
        RuntimeError: the package is not on the file system (imported from a zip file);
            Jinja2, Starlette and Alembic need real folders.
    """
    found = files("app")
    if not isinstance(found, Path):
        raise RuntimeError(f"ACV's app package must be installed on the file system: {found}")
    return found


def import_root() -> Path:
    """The folder that holds the ``app`` and ``engine`` packages: a checkout's root, or the
    ``site-packages`` (or ``pip install --target``) folder of a wheel install. Child
    processes get it on ``PYTHONPATH``, so that they import the same code."""
    return package_dir().parent


def child_pythonpath() -> str:
    """``PYTHONPATH`` for a child process (a run, a backfill): :func:`import_root`, then
    this process's own ``PYTHONPATH``."""
    return os.pathsep.join(filter(None, [str(import_root()), os.environ.get("PYTHONPATH")]))


def resource_dir(name: Folder) -> Path:
    """One of the app's resource folders: inside the package (a wheel), else at the root of
    the checkout that the package belongs to.

    Raises:
        FileNotFoundError: neither holds it (a broken install).
    """
    inside = package_dir() / name
    if inside.is_dir():
        return inside
    root = import_root()
    beside = root / name
    if beside.is_dir() and (root / "pyproject.toml").is_file():  # ACV's checkout, no other
        return beside
    raise FileNotFoundError(f"ACV's {name} folder is missing: neither {inside} nor {beside}")


TEMPLATES_DIR = resource_dir("templates")
STATIC_DIR = resource_dir("static")
MIGRATIONS_DIR = resource_dir("migrations")
