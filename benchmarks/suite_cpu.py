"""Where the test suite's CPU goes, per module, servers and Chromium included.

A pytest plugin and its summary. Each xdist worker moves itself into a cgroup of its own
(cgroup v1 ``cpuacct``, as root), so every process it starts (``acv serve``, Playwright's
Chromium, run processes) is counted with it; the cgroup's usage is read around every test.
``resource.getrusage`` would miss Chromium, whose processes are not waited for by the worker.
This is a measurement aid, not a ratio against a reference: it says which modules cost most.

Record (from the repository root; the README's test command plus the plugin)::

    CPU_PROFILE_DIR=/tmp/suite-cpu PYTHONPATH=benchmarks .venv/bin/pytest -p suite_cpu \\
      -n 2 --dist loadscope -m "not slow" -q

Summarise::

    .venv/bin/python benchmarks/suite_cpu.py /tmp/suite-cpu [--top 30]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

import pytest

CGROUPS = Path("/sys/fs/cgroup/cpuacct")
_worker: dict[str, Any] = {}


def pytest_configure(config: pytest.Config) -> None:
    """Put this xdist worker (and what it will start) into its own cgroup."""
    name = os.environ.get("PYTEST_XDIST_WORKER")
    if name is None:  # the controller runs no tests
        return
    group = CGROUPS / f"acv_suite_{name}"
    group.mkdir(exist_ok=True)
    (group / "cgroup.procs").write_text(str(os.getpid()))
    folder = Path(os.environ["CPU_PROFILE_DIR"])
    folder.mkdir(parents=True, exist_ok=True)
    _worker.update(group=group, out=(folder / f"{name}.jsonl").open("a"))


def _cpu_s() -> float:
    return int((_worker["group"] / "cpuacct.usage").read_text()) / 1e9


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """One JSON line per test: its id, the cgroup's CPU seconds and the wall seconds."""
    if not _worker:
        yield
        return
    cpu, wall = _cpu_s(), time.time()
    yield
    out: TextIO = _worker["out"]
    row = {"id": item.nodeid, "cpu": _cpu_s() - cpu, "wall": time.time() - wall}
    out.write(json.dumps(row) + "\n")
    out.flush()


def summary(folder: Path, top: int) -> str:
    """The suite's CPU seconds, then the ``top`` modules by CPU (seconds, share, wall, tests)."""
    rows = [json.loads(line) for path in folder.glob("*.jsonl") for line in path.open()]
    modules: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0, 0])
    for row in rows:
        module = modules[row["id"].split("::")[0]]
        module[0] += row["cpu"]
        module[1] += row["wall"]
        module[2] += 1
    total = sum(m[0] for m in modules.values())
    lines = [f"tests {len(rows)}, CPU {total:.0f} s"]
    for name, (cpu, wall, n) in sorted(modules.items(), key=lambda kv: -kv[1][0])[:top]:
        lines.append(f"{cpu:8.1f} s {100 * cpu / total:5.1f}% wall {wall:7.1f} s {n:5d}  {name}")
    return "\n".join(lines)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="Summarise a suite_cpu recording.")
    parser.add_argument("folder", type=Path)
    parser.add_argument("--top", type=int, default=30)
    args = parser.parse_args()
    print(summary(args.folder, args.top))
