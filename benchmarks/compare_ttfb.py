"""Time to first byte of a 10-checkpoint run's compare page and conformance curve, cold.

Trains one small ``bipars-em`` run with 10 checkpoints on a Humanoid study (a server of
``--after`` code with its worker, which stores the checkpoint artefacts), then for each code
tree (``--before``, e.g. /work/main; ``--after``, this repository) starts a fresh ``acv serve``
process without a run worker on the same data, removes any on-disk agent-tree cache, and times
the first byte of ``GET /runs/{id}/compare`` and then ``GET /api/runs/{id}/conformance-curve``.
Prints one line per measurement; the last line is JSON with the ratios before / after.

    python benchmarks/compare_ttfb.py --before /work/main --after .
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

TOKEN = "compare-ttfb-admin-token-0123456789abcdef"
ADMIN = {"Authorization": f"Bearer {TOKEN}"}
RUN = {
    "algo": "bipars-em",
    "timesteps": 2560,
    "checkpoint_every": 256,
    "n_envs": 1,
    "num_steps": 128,
    "num_minibatches": 4,
    "update_epochs": 2,
    "seed": 0,
}


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def server(code: Path, data: Path, *, worker: bool) -> Iterator[str]:
    """``acv serve`` from the code tree ``code`` on ``data``; yields the base URL."""
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "ACV_RAY_ADDRESS")}
    env |= {
        "PYTHONPATH": str(code),
        "ACV_DATA_DIR": str(data),
        "ACV_ADMIN_TOKEN": TOKEN,
        "ACV_RUN_WORKER": "true" if worker else "false",
    }
    port = _port()
    with (data / f"server-{port}.log").open("w") as log:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-c",
                "from app.cli import main; main()",
                "serve",
                "--port",
                str(port),
                "--no-access-log",
            ],
            cwd=code,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        base = f"http://127.0.0.1:{port}"
        try:
            _until(lambda: _healthy(base), 120)
            yield base
        finally:
            proc.terminate()
            proc.wait(timeout=120)


def _healthy(base: str) -> bool:
    try:
        return httpx.get(f"{base}/healthz", timeout=2).status_code == 200
    except httpx.TransportError:
        return False


def _until(predicate, timeout_s: float) -> object:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if value := predicate():
            return value
        time.sleep(0.5)
    raise TimeoutError("gave up waiting")


def train(base: str) -> int:
    """A study, a participant who always picks side a, and a finished 10-checkpoint run."""
    with httpx.Client(base_url=base, headers=ADMIN, timeout=60) as api:
        study = api.post(
            "/api/studies",
            json={"name": "ttfb", "env_id": "Humanoid-v5", "n_candidates": 16, "seed": 5},
        ).json()
        _until(lambda: api.get(f"/api/studies/{study['id']}").json()["status"] == "ready", 300)
        invite = api.post(f"/api/studies/{study['id']}/participants").json()
        me = {"Authorization": f"Bearer {invite['token']}"}
        while (m := api.get("/api/participants/me/next-match", headers=me)).status_code == 200:
            api.post(
                f"/api/matches/{m.json()['match_id']}/label",
                headers=me,
                json={"winner": m.json()["a"]["candidate_id"]},
            ).raise_for_status()
        run = api.post(
            "/api/runs", json={"study_id": study["id"], "participant_id": invite["id"], **RUN}
        ).json()
        done = _until(
            lambda: (
                (r := api.get(f"/api/runs/{run['id']}").json())["status"]
                not in ("queued", "running")
                and r
            ),
            1800,
        )
        assert done["status"] == "succeeded", done
        return run["id"]


def ttfb(client: httpx.Client, path: str) -> float:
    """Seconds from sending ``GET path`` to its first response byte."""
    start = time.perf_counter()
    with client.stream("GET", path) as response:
        next(response.iter_raw())
        first = time.perf_counter() - start
        assert response.status_code == 200, (path, response.status_code)
    return first


def measure(code: Path, data: Path, run_id: int) -> dict[str, float]:
    shutil.rmtree(data / "runs" / str(run_id) / "agent_trees", ignore_errors=True)
    with server(code, data, worker=False) as base, httpx.Client(base_url=base, timeout=600) as web:
        form = web.get("/login").text
        csrf = re.search(r'name="csrf_token" value="([^"]+)"', form).group(1)
        web.post("/login", data={"csrf_token": csrf, "token": TOKEN, "next": "/"})
        page = ttfb(web, f"/runs/{run_id}/compare")
        web.headers.update(ADMIN)
        curve = ttfb(web, f"/api/runs/{run_id}/conformance-curve")
    return {"page_s": page, "curve_s": curve}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True)
    parser.add_argument("--after", type=Path, default=Path("."))
    args = parser.parse_args()
    data = Path(tempfile.mkdtemp(prefix="acv-ttfb-"))
    with server(args.after.resolve(), data, worker=True) as base:
        run_id = train(base)
    results = {
        name: measure(code.resolve(), data, run_id)
        for name, code in (("before", args.before), ("after", args.after))
    }
    for name, r in results.items():
        print(
            f"{name}: compare page {r['page_s'] * 1000:.1f} ms, "
            f"conformance curve {r['curve_s'] * 1000:.1f} ms"
        )
    print(
        json.dumps(
            {
                "checkpoints": 10,
                **{f"{n}_{k}": round(v, 4) for n, r in results.items() for k, v in r.items()},
                "curve_ratio": round(results["before"]["curve_s"] / results["after"]["curve_s"], 1),
                "page_ratio": round(results["before"]["page_s"] / results["after"]["page_s"], 1),
            }
        )
    )


if __name__ == "__main__":
    main()
