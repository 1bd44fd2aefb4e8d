"""What a fresh ``acv serve`` or ``acv`` process imports before it does anything.

Every server start, CLI call and test subprocess pays its imports. scipy.stats (~2 s here) and
matplotlib (~1 s) are loaded where a statistic or a figure is made, torch and MuJoCo where
training or rendering happens: never by importing the web app or registering the commands.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.process

REPO = Path(__file__).resolve().parents[3]
LOADED_ON_USE = ["scipy.stats", "scipy.optimize", "matplotlib", "torch", "mujoco"]
PROBE = """
import json, sys
import app.main
from app.cli import _register_commands
_register_commands()
print(json.dumps([name for name in sys.argv[1:] if name in sys.modules]))
"""


def test_the_web_app_and_the_commands_import_no_heavy_library() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PROBE, *LOADED_ON_USE],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout) == []
