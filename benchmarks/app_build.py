"""What a new app costs in CPU before it answers its first write, in one process.

``create_app`` builds an app; on its first write the credentials-first middleware reads the
OpenAPI document (:mod:`app.http.credentials_first`). The apps of one process share one
document (``app.main._shared_openapi``); the reference, measured in the same run, is what
each app paid before: FastAPI generating the document for that app alone. Each of ``--apps``
apps (default 5; a test module builds one or more) is built, then asked for both. Prints the
median CPU milliseconds of each and their ratio.

The last line is JSON. Tests never assert timings.

Usage:
    python benchmarks/app_build.py [--apps 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from fastapi import FastAPI

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from app.main import create_app  # noqa: E402
from app.settings import Settings  # noqa: E402


def cpu_ms(call: Callable[[], Any]) -> float:
    """The process CPU time of ``call()``, in milliseconds."""
    start = time.process_time()
    call()
    return (time.process_time() - start) * 1000


def one_app(settings: Settings) -> dict[str, float]:
    """Building one app, its shared document, and FastAPI's own generation for it."""
    built: list[FastAPI] = []
    build = cpu_ms(lambda: built.append(create_app(settings)))
    app = built[0]
    shared = cpu_ms(app.openapi)
    app.openapi_schema = None  # the first app's generation cached it: the reference regenerates
    return {"build": build, "shared": shared, "per_app": cpu_ms(partial(FastAPI.openapi, app))}


def measure(apps: int) -> dict[str, list[float]]:
    """Each measure of :func:`one_app`, for ``apps`` apps built one after another."""
    with tempfile.TemporaryDirectory() as data:
        settings = Settings(data_dir=Path(data), admin_token="b" * 32)
        runs = [one_app(settings) for _ in range(apps)]
    return {name: [run[name] for run in runs] for name in runs[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--apps", type=int, default=5)
    times = measure(parser.parse_args().apps)
    medians = {name: round(statistics.median(values), 1) for name, values in times.items()}
    # The first app generates the shared document: the median is that of the later apps.
    ratio = medians["shared"] / medians["per_app"]
    print(f"create_app: {medians['build']} ms of CPU (median)")
    first = round(times["shared"][0], 1)
    print(f"OpenAPI document, shared per process: {medians['shared']} ms (the first app: {first})")
    print(f"OpenAPI document, generated per app (the reference): {medians['per_app']} ms")
    print(f"ratio shared / per app: {ratio:.4f}")
    print(
        json.dumps(
            {"median_cpu_ms": medians, "ratio": round(ratio, 4), "apps": len(times["build"])}
        )
    )


if __name__ == "__main__":
    main()
