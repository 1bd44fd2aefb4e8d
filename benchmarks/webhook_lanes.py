"""A healthy webhook receiver's lag beside receivers that never answer (issue 45 §3), on
SQLite.

Starts ``acv serve`` itself (a fresh data dir, webhooks to 127.0.0.1 only) and prepares a
study with an open link, whose webhook is a receiver on 127.0.0.1 that answers 200 at once.
Then, twice, ``--events`` visitors of the link (default 40, one every ``--every-ms``, default
100) decline consent, each a ``participant.declined`` event:

1. alone: the fast receiver is the study's only webhook (the reference);
2. beside ``--stalled`` receivers (default 1) that accept the connection, read the request
   and never answer, registered on the same study before the events.

Prints, for each, the fast receiver's lag (from the event's own ``timestamp`` to its arrival)
p50/p99/max over the events that arrived within ``--timeout-s`` (default 60) of the last
one's writing, how many did not, and how many requests the stalled receivers held. Stalling
as many receivers as ``ACV_WEBHOOK_CONCURRENCY`` (``--concurrency``, the server's default 8)
takes every lane, and the fast receiver then waits: this shows that too. The last line is
JSON.

Usage:
    python benchmarks/webhook_lanes.py [--events 40] [--every-ms 100] [--stalled 1]
        [--concurrency N] [--timeout-s 60]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
ADMIN_TOKEN = "webhook-lanes-benchmark-admin-token-0123456789"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}
CSRF_RE = re.compile(r'name="csrf_token" value="([^"]+)"')

sys.path.insert(0, str(REPO))  # test-support helpers: the server launcher, the receivers
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env  # noqa: E402
from tests.support.webhooks import Receiver, StalledReceiver  # noqa: E402


def prepare(api: httpx.Client) -> tuple[int, str]:
    """A ready study with an open link that asks for consent; its id and the link's slug."""
    body = {"name": "lanes", "env_id": "Hopper-v5", "n_candidates": 4, "seed": 1}
    study = api.post("/api/studies", json=body).raise_for_status().json()["id"]
    while (status := api.get(f"/api/studies/{study}").json()["status"]) == "preparing":
        time.sleep(0.2)
    if status != "ready":
        raise SystemExit(f"study preparation failed: {status}")
    crowd = {"enabled": True, "max_participants": 50, "consent_text": "We keep your choices."}
    link = api.put(f"/api/studies/{study}/crowd", json=crowd).raise_for_status().json()
    return study, link["slug"]


def register(api: httpx.Client, study: int, url: str) -> None:
    api.post("/api/webhooks", json={"study_id": study, "url": url}).raise_for_status()


def decline(base: str, slug: str) -> None:
    """A visitor of the link (a cookie jar of their own) who declines consent."""
    with httpx.Client(base_url=base, timeout=HTTP_TIMEOUT_S) as visitor:
        form = visitor.get(f"/s/{slug}").raise_for_status()
        token = CSRF_RE.search(form.text)
        if token is None:
            raise SystemExit("the open link showed no consent form")
        sent = {"csrf_token": token.group(1), "decision": "decline"}
        visitor.post(f"/s/{slug}", data=sent).raise_for_status()


def phase(
    base: str, slug: str, fast: Receiver, *, events: int, every_s: float, timeout_s: float
) -> dict[str, float]:
    """Send ``events`` declines and wait, ``timeout_s`` at most, until the fast receiver has
    them; the lags of those it got, in ms, and how many it did not."""
    before = len(fast.received())
    for _ in range(events):
        decline(base, slug)
        time.sleep(every_s)
    deadline = time.monotonic() + timeout_s
    while len(got := fast.received()) < before + events and time.monotonic() < deadline:
        time.sleep(0.05)
    lags = [1000 * d.lag_s for d in got[before:]] or [float("nan")]
    p50, p99 = np.percentile(lags, [50, 99])
    late = before + events - len(got)
    return {"p50_ms": float(p50), "p99_ms": float(p99), "max_ms": max(lags), "missing": late}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=40)
    parser.add_argument("--every-ms", type=float, default=100.0)
    parser.add_argument("--stalled", type=int, default=1)
    parser.add_argument("--concurrency", type=int, default=None)
    parser.add_argument("--timeout-s", type=float, default=60.0)
    args = parser.parse_args()
    results: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as data, ExitStack() as stack:
        lanes = {"ACV_WEBHOOK_CONCURRENCY": str(args.concurrency)} if args.concurrency else {}
        env = clean_env(
            ACV_DATA_DIR=data,
            ACV_ADMIN_TOKEN=ADMIN_TOKEN,
            ACV_RUN_WORKER="0",
            ACV_WEBHOOK_TARGETS="loopback",
            **lanes,
        )
        base = stack.enter_context(acv_serve(env, Path(data) / "serve.log"))
        api = stack.enter_context(
            httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S)
        )
        fast = stack.enter_context(Receiver())
        study, slug = prepare(api)
        register(api, study, fast.url())

        def measure() -> dict[str, float]:
            every_s, timeout_s = args.every_ms / 1000, args.timeout_s
            return phase(base, slug, fast, events=args.events, every_s=every_s, timeout_s=timeout_s)

        results["alone"] = measure()
        stalled = stack.enter_context(StalledReceiver())
        for n in range(args.stalled):
            register(api, study, stalled.url(f"/stalled-{n}"))
        results["beside_stalled"] = measure()
        held = stalled.requests
    for name, found in results.items():
        print(
            f"{name:>15}: fast receiver's lag p50 {found['p50_ms']:7.1f} ms, "
            f"p99 {found['p99_ms']:7.1f} ms, max {found['max_ms']:7.1f} ms; "
            f"{found['missing']:.0f} not arrived"
        )
    ratio = results["beside_stalled"]["p99_ms"] / results["alone"]["p99_ms"]
    print(f"{args.stalled} stalled receiver(s) held {held} requests; p99 ratio {ratio:.2f}")
    report = {"events": args.events, "stalled": args.stalled, "held": held, **results}
    print(json.dumps({"webhook_lanes": report | {"p99_ratio": ratio}}))


if __name__ == "__main__":
    main()
