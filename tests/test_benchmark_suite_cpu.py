"""benchmarks/suite_cpu.py's summary: per-module CPU from the workers' JSON lines."""

from __future__ import annotations

import json
from pathlib import Path

from tests.support.benchmarks import load_benchmark


def test_modules_are_summed_over_workers_and_ranked_by_cpu(tmp_path: Path) -> None:
    rows = {
        "gw0": [("tests/a.py::t1", 1.0), ("tests/b.py::t1", 5.0)],
        "gw1": [("tests/a.py::t2", 2.0)],
    }
    for worker, tests in rows.items():
        lines = [json.dumps({"id": i, "cpu": c, "wall": 2 * c}) for i, c in tests]
        (tmp_path / f"{worker}.jsonl").write_text("\n".join(lines) + "\n")
    text = load_benchmark("suite_cpu").summary(tmp_path, top=5).splitlines()
    assert text[0] == "tests 3, CPU 8 s"
    assert text[1].split() == ["5.0", "s", "62.5%", "wall", "10.0", "s", "1", "tests/b.py"]
    assert text[2].split() == ["3.0", "s", "37.5%", "wall", "6.0", "s", "2", "tests/a.py"]
