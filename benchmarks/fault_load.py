"""Labelling under load with faults: nothing lost, nothing doubled, no 5xx.

For each backend (SQLite, then PostgreSQL on a throwaway cluster), starts the real server
(``acv serve``, migrations included) on 127.0.0.1 with a fresh data dir, creates a study, and:

1. reference: one participant alone labels a whole bracket, request after request;
2. load: ``--participants`` participants (default 50) label their brackets concurrently. Each
   sends every label twice at once (one ``201``, one ``200``); a ``--race-share`` of the
   matches instead get two different answers at once (one ``201``, the loser ``409``),
   followed by the winner again. Participants think ``[0.5, 1.5] x --think-ms`` per match.
   Its label latencies are the figures;
3. crash: the same load on as many fresh participants, and once ``--kill-at`` of their
   matches are acknowledged the server gets ``kill -9``, is started again on the same data
   dir and port, and participants resume (failed requests are retried from ``next-match``).

Then the database must hold every label that got a 2xx, with its acknowledged winner, one
label per match, and every bracket complete. The last line is JSON: per backend, labels
sent (requests) and stored, duplicates, acknowledged labels lost, 409s, 5xx, and the p50 and
p99 latency of label requests against the lone participant's p50 (the reference).

Usage:
    python benchmarks/fault_load.py [--participants 50] [--candidates 16] [--env Humanoid-v5]
        [--think-ms 1000] [--race-share 0.25] [--kill-at 0.4] [--backends sqlite postgresql]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import httpx
import numpy as np
from sqlalchemy import select

from app.db import make_engine, make_sessions
from app.models import Label

ADMIN_TOKEN = "fault-benchmark-admin-token-0123456789"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
REPO = Path(__file__).resolve().parents[1]
RETRY_S = 0.2  # pause before retrying after a failed request (the server is down)


@dataclass(frozen=True)
class LoadConfig:
    """The size and shape of one load run."""

    participants: int = 50
    candidates: int = 16
    env_id: str = "Humanoid-v5"
    think_ms: float = 1000.0
    race_share: float = 0.25
    kill_at: float = 0.4
    timeout_s: float = 600.0


@dataclass
class Tally:
    """What the participants saw; ``acked`` maps a match id to its acknowledged winner."""

    posts: int = 0
    acked: dict[int, int] = field(default_factory=dict)
    conflicts: int = 0
    server_errors: int = 0
    transport_errors: int = 0
    races: int = 0
    race_losers_409: int = 0
    unexpected: list[str] = field(default_factory=list)
    label_ms: list[float] = field(default_factory=list)
    kills: int = 0
    restart_s: float = 0.0
    finished: int = 0


class Server:
    """``acv serve`` on a fixed port and data dir, which can be killed and started again."""

    def __init__(self, data_dir: Path, database_url: str | None) -> None:
        self.data_dir, self.port = data_dir, _free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        env = {k: v for k, v in os.environ.items() if k != "DATABASE_URL"}
        self.env = env | {"ACV_DATA_DIR": str(data_dir), "ACV_ADMIN_TOKEN": ADMIN_TOKEN}
        if database_url:
            self.env["DATABASE_URL"] = database_url
        self.log = data_dir / "server.log"
        self.proc: subprocess.Popen | None = None

    def start(self, timeout_s: float = 120.0) -> None:
        with self.log.open("a") as log:
            self.proc = subprocess.Popen(
                [
                    sys.executable,
                    "-c",
                    "from app.cli import main; main()",
                    "serve",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    str(self.port),
                    "--no-access-log",
                ],
                cwd=REPO,
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"the server exited:\n{self.log.read_text()[-3000:]}")
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"{self.base}/healthz", timeout=2).status_code == 200:
                    return
            time.sleep(0.1)
        raise RuntimeError("the server did not become healthy")

    def kill(self) -> None:
        """``kill -9``: no shutdown handlers, no flushing, connections cut."""
        self.proc.kill()
        self.proc.wait(timeout=30)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(timeout=60)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def prepare(base: str, config: LoadConfig, count: int) -> tuple[int, list[tuple[int, str]]]:
    """A ready study and ``count`` invited participants ``(id, token)``."""
    body = {
        "name": "fault load",
        "env_id": config.env_id,
        "n_candidates": config.candidates,
        "p": 0.9,
        "seed": 0,
        "sampling": "uniform",
        "instructions": "",
    }
    study = httpx.post(
        f"{base}/api/studies", json=body, headers=ADMIN, timeout=60
    ).raise_for_status()
    study_id = study.json()["id"]
    while (
        status := httpx.get(f"{base}/api/studies/{study_id}", headers=ADMIN, timeout=60).json()[
            "status"
        ]
    ) == "preparing":
        time.sleep(0.1)
    if status != "ready":
        raise RuntimeError(f"study preparation failed: {status}")
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
    return study_id, [(p["id"], p["token"]) for p in people]


async def _post(
    client: httpx.AsyncClient, headers: dict[str, str], match_id: int, winner: int, tally: Tally
) -> int | None:
    """One label request; its status, or ``None`` when the connection failed."""
    tally.posts += 1
    t0 = time.perf_counter()
    try:
        response = await client.post(
            f"/api/matches/{match_id}/label", headers=headers, json={"winner": winner}
        )
    except httpx.TransportError:
        tally.transport_errors += 1
        return None
    tally.label_ms.append((time.perf_counter() - t0) * 1000)
    tally.server_errors += response.status_code >= 500
    tally.conflicts += response.status_code == 409
    if response.status_code in (200, 201) and tally.acked.setdefault(match_id, winner) != winner:
        tally.unexpected.append(f"match {match_id}: 2xx for both winners")
    return response.status_code


async def _decide(
    client: httpx.AsyncClient,
    headers: dict[str, str],
    match: dict,
    rng: np.random.Generator,
    config: LoadConfig,
    tally: Tally,
) -> None:
    """Send one decision twice at once, or race two different ones, as the config says."""
    mid, sides = match["match_id"], [match["a"]["candidate_id"], match["b"]["candidate_id"]]
    winner = sides[int(rng.integers(2))]
    race = rng.random() < config.race_share
    answers = [winner, sides[0] + sides[1] - winner] if race else [winner, winner]
    codes = await asyncio.gather(*(_post(client, headers, mid, w, tally) for w in answers))
    if None in codes:
        return  # the server went down meanwhile: next-match tells what was stored
    if race:
        tally.races += 1
        tally.race_losers_409 += sorted(codes) in ([200, 409], [201, 409])
        if sorted(codes) not in ([200, 409], [201, 409]):
            tally.unexpected.append(f"race on match {mid}: {codes}")
        await _post(client, headers, mid, tally.acked.get(mid, winner), tally)
    elif sorted(codes) not in ([200, 201], [200, 200]):
        tally.unexpected.append(f"duplicate label of match {mid}: {codes}")


async def participant(
    client: httpx.AsyncClient,
    token: str,
    seed: int,
    config: LoadConfig,
    tally: Tally,
    deadline: float,
) -> bool:
    """Label the whole bracket, resuming after failures; whether it was finished in time."""
    rng = np.random.default_rng(seed)
    headers = {"Authorization": f"Bearer {token}"}
    await asyncio.sleep(config.think_ms * rng.uniform(0, 1) / 1000)
    while time.monotonic() < deadline:
        try:
            response = await client.get("/api/participants/me/next-match", headers=headers)
        except httpx.TransportError:
            tally.transport_errors += 1
            await asyncio.sleep(RETRY_S)
            continue
        if response.status_code == 204:
            return True
        if response.status_code != 200:
            tally.server_errors += response.status_code >= 500
            tally.unexpected.append(f"next-match: {response.status_code}")
            await asyncio.sleep(RETRY_S)
            continue
        await asyncio.sleep(config.think_ms * rng.uniform(0.5, 1.5) / 1000)
        await _decide(client, headers, response.json(), rng, config, tally)
    return False


async def crash_midway(server: Server, tally: Tally, total: int, config: LoadConfig) -> None:
    """``kill -9`` the server once ``kill_at`` of all matches are acknowledged; restart."""
    while len(tally.acked) < config.kill_at * total:
        await asyncio.sleep(0.02)
    await asyncio.to_thread(server.kill)
    tally.kills += 1
    t0 = time.perf_counter()
    await asyncio.to_thread(server.start)
    tally.restart_s = time.perf_counter() - t0


async def run_load(
    server: Server | None, base: str, tokens: list[str], config: LoadConfig
) -> Tally:
    """Participants label concurrently; with a ``server``, it is killed midway."""
    tally = Tally()
    limits = httpx.Limits(max_connections=2 * len(tokens), keepalive_expiry=3.0)
    deadline = time.monotonic() + config.timeout_s
    async with httpx.AsyncClient(base_url=base, limits=limits, timeout=60) as client:
        crash = (
            asyncio.create_task(
                crash_midway(server, tally, len(tokens) * (config.candidates - 1), config)
            )
            if server is not None
            else None
        )
        done = await asyncio.gather(
            *(participant(client, tok, k, config, tally, deadline) for k, tok in enumerate(tokens))
        )
        if crash is not None:
            crash.cancel()  # a no-op once done; else all finished first, and kills == 0
            with contextlib.suppress(asyncio.CancelledError):
                await crash  # re-raises a failed restart
    tally.finished = sum(done)
    return tally


def stored_labels(database_url: str, participant_ids: list[int]) -> dict[int, list[int]]:
    """Match id -> winners stored (one each, unless the database lost its constraint)."""
    engine = make_engine(database_url)
    try:
        with make_sessions(engine)() as session:
            rows = session.execute(
                select(Label.match_id, Label.winner).where(
                    Label.participant_id.in_(participant_ids)
                )
            )
            stored: dict[int, list[int]] = {}
            for match_id, winner in rows:
                stored.setdefault(match_id, []).append(winner)
            return stored
    finally:
        engine.dispose()


def pct(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)), 2) if values else float("nan")


def run_backend(
    config: LoadConfig, database_url: str | None, data_dir: Path, *, steady: bool = True
) -> dict:
    """On one backend: the reference, a steady load (latency; unless ``steady`` is off),
    and the same load on fresh participants with a ``kill -9`` midway; the figures."""
    server = Server(data_dir, database_url)
    k = config.participants
    server.start()
    try:
        _, people = prepare(server.base, config, (2 if steady else 1) * k + 1)
        tokens = [tok for _, tok in people]
        solo = LoadConfig(**{**asdict(config), "think_ms": 0.0, "race_share": 0.0})
        alone = asyncio.run(run_load(None, server.base, tokens[:1], solo))
        calm = (
            asyncio.run(run_load(None, server.base, tokens[1 : k + 1], config)) if steady else None
        )
        crashed = asyncio.run(run_load(server, server.base, tokens[-k:], config))
    finally:
        server.stop()
    stored = stored_labels(
        database_url or f"sqlite:///{data_dir / 'acv.sqlite3'}", [pid for pid, _ in people[1:]]
    )
    return figures([t for t in (calm, crashed) if t is not None], stored, alone, config) | {
        "kills": crashed.kills,
        "restart_s": round(crashed.restart_s, 2),
        "crash_run_p99_ms": pct(crashed.label_ms, 99),
    }


def figures(
    runs: list[Tally], stored: dict[int, list[int]], alone: Tally, config: LoadConfig
) -> dict:
    """Integrity over all ``runs``; latency of the first (the steady one, if any)."""
    acked = {m: w for run in runs for m, w in run.acked.items()}
    lost = [m for m, w in acked.items() if stored.get(m) != [w]]
    p50, p99, ref = pct(runs[0].label_ms, 50), pct(runs[0].label_ms, 99), pct(alone.label_ms, 50)
    return {
        "labels_sent": sum(r.posts for r in runs),
        "labels_acknowledged": len(acked),
        "labels_stored": sum(map(len, stored.values())),
        "duplicates": sum(len(w) - 1 for w in stored.values()),
        "lost": len(lost),
        "expected": len(runs) * config.participants * (config.candidates - 1),
        "finished": sum(r.finished for r in runs),
        "conflicts_409": sum(r.conflicts for r in runs),
        "races": sum(r.races for r in runs),
        "race_losers_409": sum(r.race_losers_409 for r in runs),
        "server_errors_5xx": sum(r.server_errors for r in runs),
        "unexpected": [u for r in runs for u in r.unexpected][:10],
        "transport_errors": sum(r.transport_errors for r in runs),
        "p50_ms": p50,
        "p99_ms": p99,
        "alone_p50_ms": ref,
        "p99_over_alone_p50": round(p99 / ref, 2),
    }


@contextlib.contextmanager
def postgres_url() -> Iterator[str]:
    """A database on a throwaway PostgreSQL cluster (the app tests' own fixture code)."""
    sys.path.insert(0, str(REPO))
    from tests.support.postgres import PostgresCluster

    cluster = PostgresCluster()
    cluster.start()
    try:
        yield cluster.create_database()
    finally:
        cluster.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    defaults = LoadConfig()
    for name in ("participants", "candidates", "think_ms", "race_share", "kill_at"):
        value = getattr(defaults, name)
        parser.add_argument(f"--{name.replace('_', '-')}", type=type(value), default=value)
    parser.add_argument("--env", default=defaults.env_id)
    parser.add_argument(
        "--backends", nargs="+", default=["sqlite", "postgresql"], choices=["sqlite", "postgresql"]
    )
    args = parser.parse_args()
    config = LoadConfig(
        args.participants, args.candidates, args.env, args.think_ms, args.race_share, args.kill_at
    )
    results = {}
    for backend in args.backends:
        with (
            tempfile.TemporaryDirectory(prefix="acv-fault-") as tmp,
            postgres_url() if backend == "postgresql" else contextlib.nullcontext() as url,
        ):
            results[backend] = got = run_backend(config, url, Path(tmp))
        print(
            f"{backend}: {got['labels_sent']} label requests for {got['expected']} "
            f"matches; stored {got['labels_stored']}, duplicates {got['duplicates']}, lost "
            f"{got['lost']}, 409s {got['conflicts_409']} ({got['race_losers_409']}/"
            f"{got['races']} race losers), 5xx {got['server_errors_5xx']}; kill -9 + "
            f"restart {got['restart_s']} s; label p99 {got['p99_ms']} ms = "
            f"{got['p99_over_alone_p50']}x the lone participant's p50"
        )
    print(
        json.dumps(
            {
                "participants": config.participants,
                "candidates": config.candidates,
                "env": config.env_id,
                "think_ms": config.think_ms,
                **results,
            }
        )
    )


if __name__ == "__main__":
    main()
