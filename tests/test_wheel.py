"""A package others can install (issue 44 §4): the wheel holds exactly ``app`` and
``engine``, with the templates, static files and migrations inside ``app``, and once
installed away from the checkout it serves the demo.

The wheel is built from a copy of the sources (the checkout gets no ``build/``), installed
with ``--no-deps`` into a folder of its own, and served from another folder with this venv's
dependencies (``PYTHONPATH`` puts the installed packages before the checkout's editable
install; no second torch). The demo's run worker is off: its 12 runs stay queued.
"""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
import subprocess
import sys
import zipfile
from pathlib import Path

import httpx
import pytest
from alembic.script import ScriptDirectory

from app.core.resources import FOLDERS, MIGRATIONS_DIR
from engine import __version__
from tests.support.server import HTTP_TIMEOUT_S, REPO, acv_serve, clean_env

pytestmark = pytest.mark.process

#: What the build reads: the project files and the packages' sources.
SOURCES = ("pyproject.toml", "setup.py", "README.md", "LICENSE", "app", "engine", *FOLDERS)
#: In the wheel, a file from each resource folder.
PACKAGED = ("app/templates/login.html", "app/static/css/acv.css", "app/migrations/env.py")
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc")


def build_wheel(into: Path) -> Path:
    """Build ACV's wheel, as ``pip wheel .`` does (offline), from a copy of the sources."""
    source = into / "source"
    source.mkdir()
    for name in SOURCES:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, source / name, ignore=IGNORED)
        else:
            shutil.copy2(REPO / name, source / name)
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    wheels = into / "dist"
    options = ["--no-deps", "--no-build-isolation", "--no-index"]
    subprocess.run([*pip, "wheel", *options, "-w", wheels, source], check=True, timeout=300)
    (wheel,) = wheels.glob("acv-*.whl")
    return wheel


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_wheel(tmp_path_factory.mktemp("wheel"))


def test_the_wheel_holds_app_and_engine_with_their_files(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    assert {n.split("/")[0] for n in names} == {"app", "engine", f"acv-{__version__}.dist-info"}
    assert set(PACKAGED) <= set(names)
    assert f"acv-{__version__}.dist-info/licenses/LICENSE" in names
    assert not [n for n in names if "__pycache__" in n]
    metadata = zipfile.ZipFile(wheel).read(f"acv-{__version__}.dist-info/METADATA").decode()
    assert f"Version: {__version__}\n" in metadata and "License-Expression: MIT\n" in metadata


def test_the_installed_wheel_serves_the_demo_away_from_the_checkout(
    wheel: Path, tmp_path: Path
) -> None:
    target, elsewhere = tmp_path / "site", tmp_path / "elsewhere"
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", "install"]
    subprocess.run([*pip, "--no-deps", "--no-index", "--target", target, wheel], check=True)
    elsewhere.mkdir()
    env = clean_env(
        PYTHONPATH=str(target),
        ACV_DATA_DIR=str(elsewhere / "data"),
        ACV_RUN_WORKER="false",
        ACV_LOG_FORMAT="json",
    )
    found = subprocess.run(
        [sys.executable, "-c", "import app, engine; print(app.__file__, engine.__version__)"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assert found == [str(target / "app" / "__init__.py"), __version__]  # not the checkout's

    log = elsewhere / "serve.log"
    with acv_serve(env, log, "--demo", cwd=elsewhere) as base:
        login = httpx.get(f"{base}/login", timeout=HTTP_TIMEOUT_S)
        css = httpx.get(f"{base}/static/css/acv.css", timeout=HTTP_TIMEOUT_S)
        invite = re.search(r"participant link: (\S+)", log.read_text())
        assert invite, log.read_text()
        participant = httpx.get(invite[1], follow_redirects=True, timeout=HTTP_TIMEOUT_S)
    assert login.status_code == 200 and "<form" in login.text  # TemplateNotFound before
    assert css.status_code == 200 and css.headers["content-type"].startswith("text/css")
    assert participant.status_code == 200, participant.text[:500]
    assert participant.headers["content-type"].startswith("text/html")

    with sqlite3.connect(elsewhere / "data" / "acv.sqlite3") as db:  # the wheel's migrations
        (version,) = db.execute("SELECT version_num FROM alembic_version").fetchone()
    assert version == ScriptDirectory(str(MIGRATIONS_DIR)).get_current_head()
    records = [json.loads(line) for line in log.read_text().splitlines() if line.startswith("{")]
    assert {"path": "/login", "status": 200} in [
        {"path": r.get("path"), "status": r.get("status")} for r in records
    ]
    assert all(r["time"].endswith("Z") and r["level"] for r in records)
