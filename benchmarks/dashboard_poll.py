"""The live dashboard's poll (issue 29 §1) on a crowd-sized study, on SQLite.

Starts ``acv serve`` itself (a fresh data dir, SQLite) and prepares four ``--candidates``
studies (default 16: a 15-match bracket) of ``--participants`` people each (default 300),
one after the other.

1. crowd: in each study everyone plays their whole bracket at once, starting within the
   first ``--think-ms`` and thinking ``[0.5, 1.5] x --think-ms`` per decision (default 2 s).
   Nobody watches the first and the last; in the two others ``--dashboards`` researchers
   (default 2) keep the study page open, i.e. poll the dashboard every 2.5 s with its ETag,
   as ``static/js/dashboard.js`` does. Prints the label requests' p50 and p99 unwatched
   and watched (each of two studies), and the polls' statuses and times.
2. poll: on the last full study, ``--rounds`` requests of each of these (default 200),
   over one keep-alive connection, interleaved so that the machine's noise falls on all
   three alike: the reference ``GET /api/studies/{id}`` (one read by primary key); the
   dashboard ``GET /api/studies/{id}/dashboard`` (its whole body: two statements); and the
   same with the last ETag as ``If-None-Match`` (a 304: one statement). Prints each one's
   median and p90, and the ratio of its median to the reference's.

The last line is JSON. Tests never assert timings.

Usage:
    python benchmarks/dashboard_poll.py [--participants 300] [--candidates 16]
        [--think-ms 2000] [--dashboards 2] [--rounds 200] [--env Hopper-v5]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx

REPO = Path(__file__).resolve().parents[1]
ADMIN_TOKEN = "dashboard-benchmark-admin-token-0123456789"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
POLL_S = 2.5  # the study page's interval (templates/_study_dashboard.html)
ORDER = ("unwatched", "watched", "watched", "unwatched")

sys.path.insert(0, str(REPO))  # test-support helpers: the server launcher
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env  # noqa: E402


def prepare(api: httpx.Client, env_id: str, n_candidates: int, count: int) -> tuple[int, list[str]]:
    """A ready study and ``count`` invite tokens."""
    body = {"name": "dashboard", "env_id": env_id, "n_candidates": n_candidates, "seed": 0}
    study_id = api.post("/api/studies", json=body).raise_for_status().json()["id"]
    while (status := api.get(f"/api/studies/{study_id}").json()["status"]) == "preparing":
        time.sleep(0.2)
    if status != "ready":
        raise SystemExit(f"study preparation failed: {status}")
    tokens: list[str] = []
    while len(tokens) < count:  # at most 500 per batch
        batch = {"count": min(500, count - len(tokens))}
        people = api.post(f"/api/studies/{study_id}/participants/batch", json=batch)
        tokens += [p["token"] for p in people.raise_for_status().json()]
    return study_id, tokens


@dataclass
class Crowd:
    """Milliseconds of the label requests and of the dashboards' polls, by status."""

    label_ms: list[float] = field(default_factory=list)
    poll_ms: dict[int, list[float]] = field(default_factory=dict)
    done: bool = False

    def merge(self, other: Crowd) -> None:
        self.label_ms += other.label_ms
        for code, ms in other.poll_ms.items():
            self.poll_ms.setdefault(code, []).extend(ms)


async def play(client: httpx.AsyncClient, token: str, think_s: float, crowd: Crowd) -> None:
    """Decide a whole bracket (side ``a``), thinking before each decision."""
    me = {"Authorization": f"Bearer {token}"}
    await asyncio.sleep(random.uniform(0, think_s))  # people do not start in step
    match = (await client.get("/api/participants/me/next-match", headers=me)).json()
    while match is not None:
        await asyncio.sleep(think_s * random.uniform(0.5, 1.5))
        body = {"winner": match["a"]["candidate_id"]}
        start = time.perf_counter()
        answer = await client.post(f"/api/matches/{match['match_id']}/label", headers=me, json=body)
        crowd.label_ms.append((time.perf_counter() - start) * 1000)
        match = answer.raise_for_status().json()["next"]


async def watch(client: httpx.AsyncClient, study_id: int, crowd: Crowd) -> None:
    """A study page open: poll the dashboard every :data:`POLL_S` with its last ETag."""
    etag = ""
    while not crowd.done:
        start = time.perf_counter()
        answer = await client.get(
            f"/api/studies/{study_id}/dashboard", headers=ADMIN | {"If-None-Match": etag}
        )
        took = (time.perf_counter() - start) * 1000
        crowd.poll_ms.setdefault(answer.status_code, []).append(took)
        etag = answer.headers.get("etag", etag)
        await asyncio.sleep(POLL_S)


async def crowd_run(
    base: str, study_id: int, tokens: list[str], think_ms: float, dashboards: int
) -> Crowd:
    crowd = Crowd()
    limits = httpx.Limits(max_connections=len(tokens) + dashboards, keepalive_expiry=3.0)
    async with httpx.AsyncClient(base_url=base, limits=limits, timeout=120) as client:
        watchers = [asyncio.create_task(watch(client, study_id, crowd)) for _ in range(dashboards)]
        await asyncio.gather(*(play(client, t, think_ms / 1000, crowd) for t in tokens))
        crowd.done = True
        await asyncio.gather(*watchers)
    return crowd


def timed(api: httpx.Client, url: str, **headers: str) -> tuple[float, httpx.Response]:
    """Milliseconds of ``GET url`` and its response."""
    start = time.perf_counter()
    response = api.get(url, headers=headers)
    return (time.perf_counter() - start) * 1000, response


def measure(api: httpx.Client, study_id: int, rounds: int) -> dict[str, list[float]]:
    """Milliseconds per request of the reference, the dashboard and the 304. The ETag
    changes as labels leave the last minute and the last 5: each 304 is asked with the ETag
    the dashboard request just before it got (and asked again if a label left meanwhile)."""
    url = f"/api/studies/{study_id}/dashboard"
    first = api.get(url).raise_for_status()
    print(f"dashboard body: {len(first.content)} bytes, {len(first.json()['participants'])} rows")
    ms: dict[str, list[float]] = {"reference": [], "dashboard": [], "unchanged": []}
    for _ in range(rounds):
        ms["reference"].append(timed(api, f"/api/studies/{study_id}")[0])
        took, full = timed(api, url)
        ms["dashboard"].append(took)
        etag = full.raise_for_status().headers["etag"]
        for _ in range(3):
            took, same = timed(api, url, **{"If-None-Match": etag})
            if same.status_code == 304:
                ms["unchanged"].append(took)
                break
            etag = same.raise_for_status().headers["etag"]
    return ms


def pct(values: list[float], q: int) -> float:
    return round(statistics.quantiles(values, n=100)[q - 1], 1) if len(values) > 1 else 0.0


def report_crowd(name: str, crowd: Crowd) -> dict[str, float]:
    polls = ", ".join(
        f"{len(v)} polls {code} (median {statistics.median(v):.1f} ms)"
        for code, v in sorted(crowd.poll_ms.items())
    )
    p50, p99 = pct(crowd.label_ms, 50), pct(crowd.label_ms, 99)
    print(
        f"{name}: {len(crowd.label_ms)} labels, p50 {p50} ms, p99 {p99} ms; {polls or 'no polls'}"
    )
    return {f"{name}_label_p50_ms": p50, f"{name}_label_p99_ms": p99}


def report_polls(ms: dict[str, list[float]]) -> dict[str, float]:
    reference, out = statistics.median(ms["reference"]), dict[str, float]()
    for name, values in ms.items():
        median = statistics.median(values)
        print(
            f"{name:>9}: median {median:6.2f} ms, p90 {pct(values, 90):6.1f} ms, "
            f"{median / reference:5.1f}x the reference"
        )
        out |= {f"{name}_ms": round(median, 2), f"{name}_ratio": round(median / reference, 2)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participants", type=int, default=300)
    parser.add_argument("--candidates", type=int, default=16)
    parser.add_argument("--think-ms", type=float, default=2000.0)
    parser.add_argument("--dashboards", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--env", default="Hopper-v5")
    args = parser.parse_args()
    random.seed(0)
    summary: dict[str, float | int] = {"participants": args.participants}
    with tempfile.TemporaryDirectory(prefix="acv-dashboard-") as data_dir:
        env = clean_env(ACV_DATA_DIR=data_dir, ACV_ADMIN_TOKEN=ADMIN_TOKEN, PYTHONPATH=str(REPO))
        with (
            acv_serve(env, Path(data_dir) / "server.log", "--no-access-log") as base,
            httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S) as api,
        ):
            crowds: dict[str, Crowd] = {"unwatched": Crowd(), "watched": Crowd()}
            for name in ORDER:  # A B B A: a drift over the run weighs on both alike
                study_id, tokens = prepare(api, args.env, args.candidates, args.participants)
                dashboards = args.dashboards if name == "watched" else 0
                crowd = asyncio.run(crowd_run(base, study_id, tokens, args.think_ms, dashboards))
                crowds[name].merge(crowd)
            for name, crowd in crowds.items():
                summary |= report_crowd(name, crowd)
            summary |= report_polls(measure(api, study_id, args.rounds))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
