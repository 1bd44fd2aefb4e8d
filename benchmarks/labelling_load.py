"""Labelling under load: many participants finish their brackets at once through the REST API.

Starts the real server (``acv serve``, migrations included) on 127.0.0.1 with a fresh data
dir, creates a study, then:

1. reference: one participant alone labels a whole bracket, request after request;
2. load: ``--participants`` simulated participants (default 50) label concurrently, each
   looking at a match for a random ``think`` time (uniform in ``[0.5, 1.5] x --think-ms``,
   default mean 1 s; people take longer) before answering, and starting within the first
   ``--think-ms``, over keep-alive connections;
3. stress: the same number of participants with no think time at all, i.e. as many
   requests in flight as participants. By Little's law latency then equals participants /
   throughput, so this run measures throughput, not a participant's experience.

It checks that every label sent was stored exactly once (the labels CSV, one row per
label) and prints label-request latencies with their ratio to the reference; the last
line is JSON with ``labels_sent``, ``labels_stored``, ``p50_ms``, ``p99_ms`` (of the load
run) and the stress run's throughput and latencies.

Usage:
    python benchmarks/labelling_load.py [--participants 50] [--candidates 16]
        [--env Humanoid-v5] [--think-ms 1000] [--database-url postgresql://...]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import csv
import io
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import numpy as np

ADMIN_TOKEN = "benchmark-admin-token-0123456789abcdef"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def server(database_url: str | None) -> Iterator[str]:
    """``acv serve`` in a subprocess on a fresh data dir; yields its base URL."""
    port = _free_port()
    with tempfile.TemporaryDirectory(prefix="acv-bench-") as data_dir:
        env = {k: v for k, v in os.environ.items() if k != "DATABASE_URL"}
        env |= {"ACV_DATA_DIR": data_dir, "ACV_ADMIN_TOKEN": ADMIN_TOKEN}
        if database_url:
            env["DATABASE_URL"] = database_url
        log = Path(data_dir) / "server.log"
        with log.open("w") as log_file:
            proc = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "from app.cli import main; main()",
                    "serve",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(port),
                    "--no-access-log",
                ],
                cwd=REPO,
                env=env,
                stdout=log_file,
                stderr=subprocess.STDOUT,
            )
        base = f"http://127.0.0.1:{port}"
        try:
            _wait_healthy(base, proc)
            yield base
        except BaseException:
            print(f"server log:\n{log.read_text()[-4000:]}", file=sys.stderr)
            raise
        finally:
            proc.terminate()
            proc.wait(timeout=60)


def _wait_healthy(base: str, proc: subprocess.Popen, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise SystemExit("the server exited")
        with contextlib.suppress(httpx.TransportError):
            if httpx.get(f"{base}/healthz", timeout=2).status_code == 200:
                return
        time.sleep(0.1)
    raise SystemExit("server did not become healthy")


def create_study(base: str, env_id: str, n: int) -> int:
    body = {
        "name": "load",
        "env_id": env_id,
        "n_candidates": n,
        "p": 0.9,
        "seed": 0,
        "sampling": "uniform",
        "instructions": "",
    }
    study = httpx.post(
        f"{base}/api/studies", json=body, headers=ADMIN, timeout=60
    ).raise_for_status()
    while (
        status := httpx.get(
            f"{base}/api/studies/{study.json()['id']}", headers=ADMIN, timeout=60
        ).json()["status"]
    ) == "preparing":
        time.sleep(0.1)
    if status != "ready":
        raise SystemExit(f"study preparation failed: {status}")
    return study.json()["id"]


def invite(base: str, study_id: int, count: int) -> list[tuple[int, str]]:
    people = (
        httpx.post(
            f"{base}/api/studies/{study_id}/participants/batch",
            headers=ADMIN,
            json={"count": count},
            timeout=60,
        )
        .raise_for_status()
        .json()
    )
    return [(p["id"], p["token"]) for p in people]


async def participant(
    client: httpx.AsyncClient,
    token: str,
    seed: int,
    think_ms: float,
    label_ms: list[float],
    next_ms: list[float],
) -> int:
    """Label the whole bracket, picking a side at random; returns labels sent."""
    rng = np.random.default_rng(seed)
    headers = {"Authorization": f"Bearer {token}"}
    sent = 0
    await asyncio.sleep(think_ms * rng.uniform(0, 1) / 1000)  # people do not start in step
    while True:
        t0 = time.perf_counter()
        response = await client.get("/api/participants/me/next-match", headers=headers)
        next_ms.append((time.perf_counter() - t0) * 1000)
        if response.status_code == 204:
            return sent
        match = response.raise_for_status().json()
        side = "a" if rng.random() < 0.5 else "b"
        if think_ms > 0:
            await asyncio.sleep(think_ms * rng.uniform(0.5, 1.5) / 1000)
        t0 = time.perf_counter()
        labelled = await client.post(
            f"/api/matches/{match['match_id']}/label",
            headers=headers,
            json={"winner": match[side]["candidate_id"]},
        )
        label_ms.append((time.perf_counter() - t0) * 1000)
        if labelled.status_code != 201:
            raise SystemExit(f"label refused: {labelled.status_code} {labelled.text}")
        sent += 1


async def run_participants(
    base: str, tokens: list[str], think_ms: float = 0.0
) -> tuple[int, list[float], list[float], float]:
    """All ``tokens`` label concurrently; returns (sent, label ms, next-match ms, seconds)."""
    label_ms: list[float] = []
    next_ms: list[float] = []
    # Drop idle connections before the server's 5 s keep-alive timeout closes them under us.
    limits = httpx.Limits(
        max_connections=len(tokens), max_keepalive_connections=len(tokens), keepalive_expiry=3.0
    )
    async with httpx.AsyncClient(base_url=base, limits=limits, timeout=60) as client:
        t0 = time.perf_counter()
        sent = await asyncio.gather(
            *(
                participant(client, tok, k, think_ms, label_ms, next_ms)
                for k, tok in enumerate(tokens)
            )
        )
        elapsed = time.perf_counter() - t0
    return sum(sent), label_ms, next_ms, elapsed


def stored_labels(base: str, study_id: int, participant_ids: set[int]) -> tuple[int, int]:
    """(labels stored for these participants, labels whose match appears more than once)."""
    text = httpx.get(f"{base}/api/studies/{study_id}/labels.csv", headers=ADMIN, timeout=60).text
    rows = [
        r for r in csv.DictReader(io.StringIO(text)) if int(r["participant_id"]) in participant_ids
    ]
    per_match = Counter(r["match_id"] for r in rows)
    return len(rows), sum(n - 1 for n in per_match.values())


@dataclass(frozen=True)
class Run:
    """One run's label and next-match latencies (ms) and its duration (s)."""

    sent: int
    label_ms: list[float]
    next_ms: list[float]
    seconds: float

    def pct(self, q: float, which: str = "label") -> float:
        return round(float(np.percentile(getattr(self, f"{which}_ms"), q)), 2)

    def line(self, name: str) -> str:
        return (
            f"{name}: {self.sent} labels in {self.seconds:.1f} s "
            f"({self.sent / self.seconds:.0f}/s); label p50 {self.pct(50)} ms, p99 "
            f"{self.pct(99)} ms, max {max(self.label_ms):.1f} ms; next-match p50 "
            f"{self.pct(50, 'next')} ms, p99 {self.pct(99, 'next')} ms"
        )


def run(base: str, tokens: list[str], think_ms: float = 0.0) -> Run:
    return Run(*asyncio.run(run_participants(base, tokens, think_ms)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=50)
    parser.add_argument("--candidates", type=int, default=16)
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument(
        "--think-ms",
        type=float,
        default=1000.0,
        help="mean time a participant looks at a match (load run)",
    )
    parser.add_argument("--database-url", default=None, help="default: SQLite in a temp dir")
    args = parser.parse_args()
    k = args.participants
    with server(args.database_url) as base:
        study_id = create_study(base, args.env, args.candidates)
        people = invite(base, study_id, 2 * k + 1)
        tokens = [tok for _, tok in people]
        solo = run(base, tokens[:1])
        load = run(base, tokens[1 : k + 1], args.think_ms)
        stress = run(base, tokens[k + 1 :])
        stored, duplicates = stored_labels(base, study_id, {pid for pid, _ in people[1:]})
        complete = sum(
            httpx.get(f"{base}/api/participants/{pid}/tree", headers=ADMIN, timeout=60).status_code
            == 200
            for pid, _ in people[1:]
        )
    sent = load.sent + stress.sent
    print(
        f"{'postgresql' if args.database_url else 'sqlite'}, {k} participants x "
        f"{args.candidates - 1} labels per run"
    )
    print(solo.line("alone (reference)"))
    print(load.line(f"load, think {args.think_ms:g} ms"))
    print(stress.line("stress, no think time"))
    print(
        f"load p99 / alone p50: {load.pct(99) / solo.pct(50):.1f}x; labels sent {sent}, "
        f"stored {stored}, duplicates {duplicates}, complete trees {complete}/{2 * k}"
    )
    print(
        json.dumps(
            {
                "database": "postgresql" if args.database_url else "sqlite",
                "participants": k,
                "candidates": args.candidates,
                "think_ms": args.think_ms,
                "labels_sent": sent,
                "labels_stored": stored,
                "duplicates": duplicates,
                "complete_trees": complete,
                "p50_ms": load.pct(50),
                "p99_ms": load.pct(99),
                "alone_p50_ms": solo.pct(50),
                "p99_over_alone_p50": round(load.pct(99) / solo.pct(50), 2),
                "stress_labels_per_s": round(stress.sent / stress.seconds, 1),
                "stress_p50_ms": stress.pct(50),
                "stress_p99_ms": stress.pct(99),
            }
        )
    )


if __name__ == "__main__":
    main()
