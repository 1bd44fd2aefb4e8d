"""``acv gold add|list|remove``, ``acv study gate|quality`` and ``acv participant
exclude|include`` (issue 28 §1): the same services as the REST API; bad input is one line on
stderr and exit code 2, and changes nothing."""

from __future__ import annotations

import re

import pytest

from tests.support.cli import acv


@pytest.fixture
def run(monkeypatch, backend_url):
    """Invoke ``acv`` in-process on this module's database."""
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    return acv


@pytest.fixture
def study_id(run) -> str:
    made = run("study", "create", "--name", "q", "--env", "Hopper-v5", "--candidates", "4")
    assert made.exit_code == 0, made.output
    return re.search(r"study (\d+) ready", made.output)[1]


def test_gold_gate_quality_and_exclusion(run, study_id: str) -> None:
    added = run("gold", "add", "--study", study_id, "--a", "0", "--b", "1", "--answer", "1")
    assert added.exit_code == 0, added.output
    item = re.search(r"gold item (\d+): pair #0 vs #1, answer #1", added.output)[1]
    assert run("gold", "list", "--study", study_id).output.split() == [item, "pair", "0", "1", "1"]
    assert run("participant", "add", "--study", study_id).exit_code == 0
    gated = run("study", "gate", "--study", study_id, "--gold-gate", "0.9", "--excludes")
    assert gated.exit_code == 0, gated.output
    assert "gate 0.9, excludes; 0 excluded" in gated.output
    table = run("study", "quality", "--study", study_id)
    assert table.exit_code == 0 and "gold 0/0" in table.output and "included" in table.output
    pid = table.output.split()[0]
    out = run("participant", "exclude", "--participant", pid, "--reason", "duplicate")
    assert out.exit_code == 0 and f"participant {pid}: duplicate" in out.output
    assert "excluded: duplicate" in run("study", "quality", "--study", study_id).output
    assert run("participant", "include", "--participant", pid).exit_code == 0
    assert run("gold", "remove", "--study", study_id, "--item", item).exit_code == 0
    assert run("gold", "list", "--study", study_id).output == ""


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("gold", "add", "--a", "0", "--b", "0", "--answer", "0"), "two different candidates"),
        (("gold", "add", "--a", "0", "--b", "9", "--answer", "0"), "candidate 9 is not one of"),
        (("gold", "add", "--a", "0", "--b", "1", "--answer", "3"), "answer must be 0 or 1"),
        (("study", "gate", "--gold-gate", "1.5"), "gold_gate must be in [0, 1]"),
        (("gold", "remove", "--item", "999"), "gold item 999"),
    ],
)
def test_bad_input_exits_2_and_changes_nothing(run, study_id: str, args, says: str) -> None:
    result = run(*args[:2], "--study", study_id, *args[2:])
    assert result.exit_code == 2, result.output
    assert says in result.stderr
    assert run("gold", "list", "--study", study_id).output == ""


def test_excluding_nobody_exits_2(run) -> None:
    result = run("participant", "exclude", "--participant", "999999")
    assert result.exit_code == 2 and "participant 999999 not found" in result.stderr
