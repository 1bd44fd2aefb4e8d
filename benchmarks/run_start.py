"""How long a run process takes to be ready to train: forked by the local executor's fork
server against a fresh interpreter (how run processes started before, the reference).

"Ready" is what a run process does before its first env step: import the training code
(``app.jobs.execute``, torch) and take one optimizer step (its first use imports
``torch._dynamo``). The fork server (:func:`app.jobs.local.fork_server`) is started once
before the timed rounds, as the worker's first run does; its start is printed apart. The two
ways alternate for ``--rounds`` rounds, so that machine noise hits them alike. Prints one line
per measurement and, last, one JSON object with the median seconds of each and their ratio.

    PYTHONPATH=. .venv/bin/python -m benchmarks.run_start [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time

import numpy as np

from app.jobs.local import fork_server

READY = "from benchmarks.run_start import ready; ready()"


def ready() -> None:
    """What a run process does before its first env step."""
    import torch

    from app.jobs.execute import execute_run  # noqa: F401 (the import is what is timed)

    net = torch.nn.Linear(4, 4)
    optimizer = torch.optim.Adam(net.parameters())
    net(torch.zeros(1, 4)).sum().backward()
    optimizer.step()


def forked() -> float:
    """Seconds to fork a ready run process from the fork server and see it exit."""
    start = time.perf_counter()
    process = fork_server().Process(target=ready, daemon=True)
    process.start()
    process.join()
    assert process.exitcode == 0, process.exitcode
    return time.perf_counter() - start


def fresh() -> float:
    """Seconds for a fresh interpreter to get ready and exit (the reference)."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", READY], check=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    print(f"fork server start and first run: {forked():.2f} s", flush=True)
    times: dict[str, list[float]] = {"fresh": [], "forked": []}
    for i in range(args.rounds):
        for name, measure in (("fresh", fresh), ("forked", forked)):
            times[name].append(measure())
            print(f"round {i}: {name} {times[name][-1]:.2f} s", flush=True)
    medians = {name: float(np.median(t)) for name, t in times.items()}
    ratio = medians["fresh"] / medians["forked"]
    print(json.dumps({"fresh_s": medians["fresh"], "forked_s": medians["forked"], "ratio": ratio}))


if __name__ == "__main__":
    main()
