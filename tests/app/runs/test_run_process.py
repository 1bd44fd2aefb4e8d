"""What the fork server of the ``local`` executor preloads for the run processes it forks."""

from __future__ import annotations

import sys
import types

import pytest

from app.jobs.run_process import PRELOAD, preload


def _main(file: str | None = None, spec: str | None = None) -> types.ModuleType:
    module = types.ModuleType("__main__")
    if file is not None:
        module.__file__ = file
    module.__spec__ = None if spec is None else types.SimpleNamespace(name=spec)  # type: ignore[assignment]
    return module


@pytest.mark.parametrize(
    ("main", "with_cli"),
    [
        (_main(), False),  # python -c ... (the tests' servers), an interactive shell
        (_main(file="/venv/bin/acv"), True),  # the acv console script
        (_main(spec="app.cli"), True),  # python -m app.cli
    ],
)
def test_the_cli_is_preloaded_when_children_run_main_again(
    monkeypatch: pytest.MonkeyPatch, main: types.ModuleType, with_cli: bool
) -> None:
    monkeypatch.setitem(sys.modules, "__main__", main)
    assert preload() == [*PRELOAD, *(["app.cli"] if with_cli else [])]
