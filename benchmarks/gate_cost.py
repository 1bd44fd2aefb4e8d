"""The gold gate's cost per answer as a study grows (issue 45 §7), on SQLite.

Starts ``acv serve`` itself (a fresh data dir) and prepares one study of ``--candidates``
(default 8: 7 bracket matches) with two gold items and the gate on, excluding. Then, for
each size in ``--sizes`` (default 10, 150, 300 participants who have played their whole
bracket, gold items included), ``--probes`` fresh participants (default 30) each send, one
request at a time over one keep-alive connection, their first bracket label (the reference)
and their first gold answer (what the gate runs after). Prints, per size, the median of each
and their ratio: a gate at constant cost keeps the ratio flat as the study grows.

The last line is JSON. Tests never assert timings.

Usage:
    python benchmarks/gate_cost.py [--sizes 10,150,300] [--probes 30] [--candidates 8]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parents[1]
ADMIN_TOKEN = "gate-cost-benchmark-admin-token-0123456789"  # >= 32 characters
ADMIN = {"Authorization": f"Bearer {ADMIN_TOKEN}"}

sys.path.insert(0, str(REPO))  # test-support helpers: the server launcher
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env  # noqa: E402


def prepare(api: httpx.Client, n_candidates: int) -> int:
    """A ready study with two gold items and the gate on (excluding)."""
    body = {"name": "gate", "env_id": "Hopper-v5", "n_candidates": n_candidates, "seed": 5}
    study = api.post("/api/studies", json=body).raise_for_status().json()["id"]
    while (status := api.get(f"/api/studies/{study}").json()["status"]) == "preparing":
        time.sleep(0.2)
    if status != "ready":
        raise SystemExit(f"study preparation failed: {status}")
    for a, b, answer in ((0, 1, 1), (2, 3, 2)):
        gold = {"kind": "pair", "a": a, "b": b, "answer": answer}
        api.post(f"/api/studies/{study}/gold", json=gold).raise_for_status()
    crowd = {"enabled": True, "max_participants": 1000, "gold_gate": 0.9, "gate_excludes": True}
    api.put(f"/api/studies/{study}/crowd", json=crowd).raise_for_status()
    return study


def invite(api: httpx.Client, study: int, count: int) -> list[str]:
    people = api.post(f"/api/studies/{study}/participants/batch", json={"count": count})
    return [p["token"] for p in people.raise_for_status().json()]


def step(api: httpx.Client, token: str) -> tuple[str, float] | None:
    """Send the participant's next answer (``a`` wins; gold answered right); returns its kind
    and milliseconds, or None when the bracket is done."""
    auth = {"Authorization": f"Bearer {token}"}
    upcoming = api.get("/api/participants/me/next-match", headers=auth)
    if upcoming.status_code == 204:
        return None
    match: dict[str, Any] = upcoming.raise_for_status().json()
    winner = match["a"]["candidate_id"]
    if match["gold"] is not None:
        url, kind = f"/api/participants/me/gold/{match['gold']['item_id']}/label", "gold"
    else:
        url, kind = f"/api/matches/{match['match_id']}/label", "label"
    start = time.perf_counter()
    api.post(url, json={"winner": winner}, headers=auth).raise_for_status()
    return kind, 1000 * (time.perf_counter() - start)


def probe(api: httpx.Client, study: int, probes: int) -> dict[str, list[float]]:
    """Each fresh participant's first label and first gold answer, in milliseconds."""
    found: dict[str, list[float]] = {"label": [], "gold": []}
    for token in invite(api, study, probes):
        firsts: dict[str, float] = {}
        while (sent := step(api, token)) is not None:
            firsts.setdefault(*sent)
        for kind in found:
            found[kind].append(firsts[kind])
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="10,150,300")
    parser.add_argument("--probes", type=int, default=30)
    parser.add_argument("--candidates", type=int, default=8)
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    results = []
    with tempfile.TemporaryDirectory() as data:
        env = clean_env(ACV_DATA_DIR=data, ACV_ADMIN_TOKEN=ADMIN_TOKEN, ACV_RUN_WORKER="0")
        with acv_serve(env, Path(data) / "serve.log") as base:
            api = httpx.Client(base_url=base, headers=ADMIN, timeout=HTTP_TIMEOUT_S)
            study, played = prepare(api, args.candidates), 0
            for size in sizes:
                for token in invite(api, study, size - played):  # the study grows to size
                    while step(api, token) is not None:
                        pass
                played = size
                found = probe(api, study, args.probes)
                played += args.probes
                label, gold = (statistics.median(found[k]) for k in ("label", "gold"))
                print(
                    f"{size:4d} participants: label {label:6.1f} ms, gold answer {gold:6.1f} ms, "
                    f"ratio {gold / label:.2f}"
                )
                results.append({"participants": size, "label_ms": label, "gold_ms": gold})
    print(json.dumps({"gate_cost": results}))


if __name__ == "__main__":
    main()
