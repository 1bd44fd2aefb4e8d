"""Labelling at crowd scale: hundreds of participants playing whole brackets at once.

Starts ``acv serve`` itself on 127.0.0.1 (a fresh data dir; SQLite, or PostgreSQL on a
throwaway cluster), prepares a study and invites ``--participants`` people, then:

1. ceiling: closed loops hammer ``/healthz`` (a trivial JSON endpoint, one ``SELECT 1``,
   served by the same stack) for a few seconds; its requests/s is the practical ceiling;
2. crowd: every participant plays their whole bracket with an asyncio client (aiohttp,
   keep-alive), sending what the labelling page (``static/js/label.js``) sends once it has
   loaded: one label per decision, whose answer carries the next match (``next``; an older
   server without it is asked ``next-match``).

   - closed loop (``--mode closed``, the default): each person thinks
     ``[0.5, 1.5] x --think-ms`` after each answer, starting within the first
     ``--start-spread-ms`` (default ``--think-ms``; 0: everyone starts in the same instant).
     Latency runs from the moment a request is sent, so a slow server slows its own load
     and hides queueing delay.
   - open loop (``--mode open``): decisions arrive at a constant rate, participants /
     ``--think-ms`` per second: person ``i`` sends decision ``k`` at
     ``t0 + (i / participants + k) x --think-ms`` (or as soon as the previous answer is in,
     if later), and latency runs from that *scheduled* time, so it includes the queueing a
     closed loop hides.

Then every acknowledged (2xx) label must be stored with its winner, once. The last line is
JSON: participants, think_ms, workers, database, labels_sent, labels_stored, lost,
duplicates, errors_5xx, labels_per_s, p50_ms and p99_ms (of every labelling request: labels
and next-match), ceiling_rps and ratio_vs_ceiling (labelling requests/s over the ceiling),
and the flash crowd's floor (issue 45 §5): first_next_p99_ms (each participant's first
next-match), healthz_burst_p99_ms (as many ``/healthz`` requests as participants, sent in the
same instant on new connections, before the crowd) and first_next_vs_floor, their ratio.

With ``--dashboards N``, N researchers' dashboards poll ``GET /api/studies/{id}/dashboard``
every 2 s (with ``If-None-Match``, as ``static/js/dashboard.js`` does) all along.

With ``--training``, a ``ppo`` run trains on the same server throughout (its executor stores a
metrics row every 128 steps in the same database): the labelling latency with run state
written to the database, to compare with a run of the same command without it.

Usage:
    python benchmarks/crowd_load.py [--database sqlite|postgresql] [--participants 300]
        [--think-ms 2000] [--mode closed|open] [--start-spread-ms MS] [--workers 1]
        [--candidates 16] [--timeout-s 300] [--dashboards 0] [--training]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import csv
import io
import json
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import aiohttp
import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
ADMIN_TOKEN = "crowd-benchmark-admin-token-0123456789"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
CEILING_S, CEILING_LOOPS = 4.0, 64


sys.path.insert(0, str(REPO))  # test-support helpers: the server launcher, a PostgreSQL cluster
from tests.support.postgres import PostgresCluster  # noqa: E402
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env  # noqa: E402


@contextlib.contextmanager
def database(kind: str) -> Iterator[str | None]:
    """``None`` for SQLite (in the data dir), else a fresh PostgreSQL database's URL."""
    if kind == "sqlite":
        yield None
        return
    cluster = PostgresCluster()
    cluster.start()
    try:
        yield cluster.create_database()
    finally:
        cluster.stop()


@contextlib.contextmanager
def server(database_url: str | None, workers: int) -> Iterator[str]:
    """``acv serve`` in a subprocess on a fresh data dir; yields its base URL."""
    with tempfile.TemporaryDirectory(prefix="acv-crowd-") as data_dir:
        env = clean_env(ACV_DATA_DIR=data_dir, ACV_ADMIN_TOKEN=ADMIN_TOKEN, PYTHONPATH=str(REPO))
        if database_url:
            env["DATABASE_URL"] = database_url
        extra = ["--workers", str(workers)] if workers != 1 else []
        log = Path(data_dir) / "server.log"
        try:
            with acv_serve(env, log, "--no-access-log", *extra) as base:
                yield base
        except BaseException:
            print(f"server log:\n{log.read_text()[-4000:]}", file=sys.stderr)
            raise


def prepare(base: str, n_candidates: int, count: int) -> tuple[int, list[str]]:
    """A ready study and ``count`` invite tokens."""
    body = {
        "name": "crowd",
        "env_id": "Humanoid-v5",
        "n_candidates": n_candidates,
        "p": 0.9,
        "seed": 0,
        "sampling": "uniform",
        "instructions": "",
    }
    study_id = (
        httpx.post(f"{base}/api/studies", json=body, headers=ADMIN, timeout=HTTP_TIMEOUT_S)
        .raise_for_status()
        .json()["id"]
    )
    while (
        status := httpx.get(
            f"{base}/api/studies/{study_id}", headers=ADMIN, timeout=HTTP_TIMEOUT_S
        ).json()["status"]
    ) == "preparing":
        time.sleep(0.1)
    if status != "ready":
        raise SystemExit(f"study preparation failed: {status}")
    tokens: list[str] = []
    while len(tokens) < count:  # at most 500 per batch
        people = httpx.post(
            f"{base}/api/studies/{study_id}/participants/batch",
            headers=ADMIN,
            json={"count": min(500, count - len(tokens))},
            timeout=HTTP_TIMEOUT_S,
        )
        tokens += [p["token"] for p in people.raise_for_status().json()]
    return study_id, tokens


def start_training(base: str, study_id: int) -> int:
    """A ``ppo`` run with a tiny update (128 steps, a metrics row each), running once the
    crowd starts: its executor writes run state rows to the same database all along."""
    body = {"study_id": study_id, "algo": "ppo", "timesteps": 10_000_000, "n_envs": 1,
            "num_steps": 128, "num_minibatches": 4, "update_epochs": 2}  # fmt: skip
    run = httpx.post(f"{base}/api/runs", json=body, headers=ADMIN, timeout=HTTP_TIMEOUT_S)
    run_id = int(run.json()["id"])
    deadline = time.monotonic() + 300
    while (
        httpx.get(f"{base}/api/runs/{run_id}/metrics", headers=ADMIN, timeout=HTTP_TIMEOUT_S).json()
        == []
    ):
        if time.monotonic() > deadline:  # the run never trained: say so, measure nothing
            raise SystemExit(f"training run {run_id} stored no metrics row in 300 s")
        time.sleep(0.2)  # training: the first metrics row is stored
    return run_id


def stop_training(base: str, run_id: int) -> int:
    """Cancel the run; the metrics rows it wrote."""
    httpx.post(f"{base}/api/runs/{run_id}/cancel", headers=ADMIN, timeout=HTTP_TIMEOUT_S)
    return len(
        httpx.get(f"{base}/api/runs/{run_id}/metrics", headers=ADMIN, timeout=HTTP_TIMEOUT_S).json()
    )


@dataclass
class Tally:
    """What the participants saw; ``acked`` maps a match id to its acknowledged winner."""

    sent: int = 0
    requests: int = 0
    errors_5xx: int = 0
    transport_errors: int = 0
    unexpected: list[str] = field(default_factory=list)
    acked: dict[int, int] = field(default_factory=dict)
    #: Latencies by request: labels, next-match, and each participant's first next-match.
    ms: dict[str, list[float]] = field(
        default_factory=lambda: {"label": [], "next": [], "first_next": []}
    )
    dashboard_polls: int = 0


async def _call(
    client: aiohttp.ClientSession,
    tally: Tally,
    kind: str,
    method: str,
    url: str,
    headers: dict[str, str],
    body: dict | None = None,
    scheduled: float | None = None,
) -> tuple[int, dict | None]:
    """One timed request: (status, JSON body or ``None``); status 0 when the connection
    failed. Its latency runs from ``scheduled`` (a ``perf_counter`` time) when given, else
    from now."""
    tally.requests += 1
    t0 = time.perf_counter() if scheduled is None else scheduled
    try:
        async with client.request(method, url, headers=headers, json=body) as response:
            data = await response.json() if response.status in (200, 201) else None
            status = response.status
    except aiohttp.ClientError:
        tally.transport_errors += 1
        return 0, None
    tally.ms[kind].append((time.perf_counter() - t0) * 1000)
    tally.errors_5xx += status >= 500
    return status, data


async def _next(
    client: aiohttp.ClientSession, tally: Tally, headers: dict[str, str], kind: str = "next"
) -> dict | None:
    status, data = await _call(
        client, tally, kind, "GET", "/api/participants/me/next-match", headers
    )
    if status not in (200, 204):
        tally.unexpected.append(f"next-match answered {status}")
    return data


@dataclass(frozen=True)
class Pace:
    """When a participant decides. ``mode``: ``closed`` (think after each answer) or
    ``open`` (a fixed schedule: ``offset_s`` then every ``think_ms``); ``start_s``: when a
    closed-loop participant starts."""

    mode: str
    think_ms: float
    start_s: float = 0.0
    offset_s: float = 0.0


async def _wait_turn(pace: Pace, rng: np.random.Generator, t0: float, k: int) -> float | None:
    """Wait until decision ``k`` is due; its scheduled time (open loop) or ``None``."""
    if pace.mode == "open":
        due = t0 + pace.offset_s + k * pace.think_ms / 1000
        await asyncio.sleep(max(0.0, due - time.perf_counter()))
        return due
    if pace.think_ms > 0:
        await asyncio.sleep(pace.think_ms * rng.uniform(0.5, 1.5) / 1000)
    return None


async def participant(
    client: aiohttp.ClientSession,
    token: str,
    seed: int,
    pace: Pace,
    n_matches: int,
    tally: Tally,
    deadline: float,
) -> None:
    """Play the whole bracket (at most ``2 x n_matches`` decisions, or until ``deadline``)."""
    rng = np.random.default_rng(seed)
    headers = {"Authorization": f"Bearer {token}"}
    t0 = time.perf_counter()
    await asyncio.sleep(pace.start_s)
    match = await _next(client, tally, headers, "first_next")
    for k in range(2 * n_matches):
        if match is None or time.monotonic() > deadline:
            return
        winner = match["a" if rng.random() < 0.5 else "b"]["candidate_id"]
        scheduled = await _wait_turn(pace, rng, t0, k + 1)
        tally.sent += 1
        status, data = await _call(
            client,
            tally,
            "label",
            "POST",
            f"/api/matches/{match['match_id']}/label",
            headers,
            {"winner": winner},
            scheduled,
        )
        if status in (200, 201):
            tally.acked[match["match_id"]] = winner
        elif status != 0:
            tally.unexpected.append(f"label answered {status}")
        match = (
            data["next"]
            if data is not None and "next" in data
            else await _next(client, tally, headers)
        )


async def _ceiling(base: str, seconds: float, loops: int) -> float:
    """Requests/s of ``/healthz`` from ``loops`` closed loops."""
    count = 0
    connector = aiohttp.TCPConnector(limit=loops)
    async with aiohttp.ClientSession(base, connector=connector) as client:
        stop = time.perf_counter() + seconds

        async def loop() -> None:
            nonlocal count
            while time.perf_counter() < stop:
                async with client.get("/healthz") as response:
                    await response.read()
                    count += response.status == 200

        t0 = time.perf_counter()
        await asyncio.gather(*(loop() for _ in range(loops)))
        return count / (time.perf_counter() - t0)


async def _floor(base: str, count: int) -> list[float]:
    """Latencies (ms) of ``count`` ``/healthz`` requests sent in the same instant, each on a
    new connection, as a flash crowd's first requests are: the HTTP floor a flash crowd's
    first ``next-match`` is compared with (issue 45 §5)."""
    connector = aiohttp.TCPConnector(limit=count, force_close=True)
    async with aiohttp.ClientSession(base, connector=connector) as client:
        start = asyncio.Event()

        async def one() -> float:
            await start.wait()
            t0 = time.perf_counter()
            async with client.get("/healthz") as response:
                await response.read()
            return (time.perf_counter() - t0) * 1000

        tasks = [asyncio.create_task(one()) for _ in range(count)]
        await asyncio.sleep(0.1)  # every task waiting on the event
        start.set()
        return list(await asyncio.gather(*tasks))


def paces(args: argparse.Namespace) -> list[Pace]:
    """Each participant's pace, from the command line (seeded: the same every run)."""
    rng = np.random.default_rng(0)
    spread = args.think_ms if args.start_spread_ms is None else args.start_spread_ms
    n = args.participants
    return [
        Pace(
            args.mode,
            args.think_ms,
            spread * rng.uniform(0, 1) / 1000,
            k / n * args.think_ms / 1000,
        )
        for k in range(n)
    ]


async def dashboard(base: str, study_id: int, stop: asyncio.Event, tally: Tally) -> None:
    """A researcher's dashboard: poll every 2 s with ``If-None-Match``, as the page does."""
    etag = None
    async with aiohttp.ClientSession(base, headers=ADMIN) as client:
        while not stop.is_set():
            headers: dict[str, str] = {"If-None-Match": etag} if etag else {}
            async with client.get(f"/api/studies/{study_id}/dashboard", headers=headers) as r:
                await r.read()
                etag = r.headers.get("ETag", etag)
                tally.dashboard_polls += 1
                tally.errors_5xx += r.status >= 500
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), 2.0)


async def crowd(
    base: str, study_id: int, tokens: list[str], args: argparse.Namespace
) -> tuple[Tally, float]:
    """Everyone plays at once (and ``--dashboards`` poll); the tally and the seconds it took."""
    tally, stop = Tally(), asyncio.Event()
    connector = aiohttp.TCPConnector(limit=len(tokens), keepalive_timeout=3.0)
    timeout = aiohttp.ClientTimeout(total=60)
    polls = [
        asyncio.create_task(dashboard(base, study_id, stop, tally)) for _ in range(args.dashboards)
    ]
    async with aiohttp.ClientSession(base, connector=connector, timeout=timeout) as client:
        t0 = time.perf_counter()
        deadline = time.monotonic() + args.timeout_s
        await asyncio.gather(
            *(
                participant(client, tok, k, pace, args.candidates - 1, tally, deadline)
                for k, (tok, pace) in enumerate(zip(tokens, paces(args), strict=True))
            )
        )
        seconds = time.perf_counter() - t0
    stop.set()
    await asyncio.gather(*polls)
    return tally, seconds


def stored_labels(base: str, study_id: int) -> list[tuple[int, int]]:
    """``(match id, winner)`` of every stored label of the study."""
    text = (
        httpx.get(
            f"{base}/api/studies/{study_id}/labels.csv", headers=ADMIN, timeout=HTTP_TIMEOUT_S
        )
        .raise_for_status()
        .text
    )
    return [(int(r["match_id"]), int(r["winner"])) for r in csv.DictReader(io.StringIO(text))]


def summary(
    args: argparse.Namespace,
    tally: Tally,
    seconds: float,
    ceiling_rps: float,
    stored: list[tuple[int, int]],
    floor_ms: list[float],
) -> dict:
    """The JSON line."""
    per_match = Counter(mid for mid, _ in stored)
    winners = dict(stored)
    lost = sum(winners.get(mid) != w for mid, w in tally.acked.items())
    every = tally.ms["label"] + tally.ms["next"] + tally.ms["first_next"]
    first_p99 = float(np.percentile(tally.ms["first_next"], 99)) if tally.ms["first_next"] else None
    floor_p99 = float(np.percentile(floor_ms, 99))
    pct = (lambda q: round(float(np.percentile(every, q)), 1)) if every else (lambda q: None)
    rps = len(every) / seconds
    return {
        "participants": args.participants,
        "think_ms": args.think_ms,
        "mode": args.mode,
        "start_spread_ms": args.think_ms if args.start_spread_ms is None else args.start_spread_ms,
        "dashboards": args.dashboards,
        "dashboard_polls": tally.dashboard_polls,
        "training": args.training,
        "workers": args.workers,
        "database": args.database,
        "labels_sent": tally.sent,
        "labels_stored": len(stored),
        "lost": lost,
        "duplicates": sum(n - 1 for n in per_match.values()),
        "errors_5xx": tally.errors_5xx,
        "labels_per_s": round(len(tally.acked) / seconds, 1),
        "p50_ms": pct(50),
        "p99_ms": pct(99),
        "max_ms": round(max(every), 1) if every else None,
        "ceiling_rps": round(ceiling_rps, 1),
        "ratio_vs_ceiling": round(rps / ceiling_rps, 3),
        "first_next_p99_ms": None if first_p99 is None else round(first_p99, 1),
        "healthz_burst_p99_ms": round(floor_p99, 1),
        "first_next_vs_floor": None if first_p99 is None else round(first_p99 / floor_p99, 3),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--database", choices=("sqlite", "postgresql"), default="sqlite")
    parser.add_argument("--participants", type=int, default=300)
    parser.add_argument("--think-ms", type=float, default=2000.0)
    parser.add_argument("--mode", choices=("closed", "open"), default="closed")
    parser.add_argument(
        "--start-spread-ms",
        type=float,
        default=None,
        help="closed loop: people start within this time (default --think-ms; 0: all at once)",
    )
    parser.add_argument("--dashboards", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--candidates", type=int, default=16)
    parser.add_argument("--timeout-s", type=float, default=300.0)
    parser.add_argument(
        "--training",
        action="store_true",
        help="a training run writes its metrics rows (one per 128 steps) all along",
    )
    args = parser.parse_args()
    with database(args.database) as url, server(url, args.workers) as base:
        study_id, tokens = prepare(base, args.candidates, args.participants)
        run_id = start_training(base, study_id) if args.training else None
        ceiling_rps = asyncio.run(_ceiling(base, CEILING_S, min(CEILING_LOOPS, args.participants)))
        floor_ms = asyncio.run(_floor(base, args.participants))
        tally, seconds = asyncio.run(crowd(base, study_id, tokens, args))
        stored = stored_labels(base, study_id)
        if run_id is not None:
            print(f"training run: {stop_training(base, run_id)} metrics rows written")
    for kind, ms in tally.ms.items():
        if ms:
            print(
                f"{kind}: {len(ms)} requests, p50 {np.percentile(ms, 50):.1f} ms, "
                f"p99 {np.percentile(ms, 99):.1f} ms, max {max(ms):.1f} ms"
            )
    print(
        f"{seconds:.1f} s; {tally.requests} requests; transport errors "
        f"{tally.transport_errors}; unexpected answers {len(tally.unexpected)} "
        f"{tally.unexpected[:3]}"
    )
    print(
        f"healthz burst: {len(floor_ms)} at once, p50 {np.percentile(floor_ms, 50):.1f} ms, "
        f"p99 {np.percentile(floor_ms, 99):.1f} ms"
    )
    print(json.dumps(summary(args, tally, seconds, ceiling_rps, stored, floor_ms)))


if __name__ == "__main__":
    main()
