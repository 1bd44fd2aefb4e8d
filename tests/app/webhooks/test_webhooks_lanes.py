"""Webhooks that never wait in line (issue 45 §3), on SQLite and PostgreSQL: a receiver that
accepts the connection and never answers, beside one that answers at once, delays none of
the fast one's events by a second; attempts in flight are at most one per webhook and
``ACV_WEBHOOK_CONCURRENCY`` in all; stopping cuts them short and leaves no thread behind;
and each event carries a per-study sequence number, unique however many write at once.
Receivers listen on 127.0.0.1 only.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.db import writing
from app.settings import Settings
from app.webhooks.delivery import Policy
from app.webhooks.outbox import Owner, emit
from app.webhooks.scheduler import Deliverer, DeliveryThread
from tests.support.wait import wait_for
from tests.support.web import ADMIN
from tests.support.webhooks import Receiver, StalledReceiver, attempts, events, webhook_settings

#: Attempts in flight at once in the app (``ACV_WEBHOOK_CONCURRENCY``): room for one stalled
#: receiver beside a healthy one, and too little for three stalled ones.
LANES = 2
#: The issue's bound on how late a healthy receiver's event may arrive.
MAX_LAG_S = 1.0


@pytest.fixture(scope="module")
def settings(backend_url: tuple[Path, str]) -> Settings:
    """Webhooks to 127.0.0.1 only, quick retries, and two attempts in flight at once."""
    return webhook_settings(backend_url, webhook_concurrency=LANES)


def register(client: TestClient, url: str, study_id: int) -> dict[str, Any]:
    response = client.post("/api/webhooks", json={"url": url, "study_id": study_id}, headers=ADMIN)
    assert response.status_code == 201, response.text
    return response.json()


def remove(client: TestClient, *hooks: dict[str, Any]) -> None:
    for hook in hooks:
        assert client.delete(f"/api/webhooks/{hook['id']}", headers=ADMIN).status_code == 204


def emitter(client: TestClient, study_id: int) -> Callable[[], None]:
    """Writes one event for the study's webhooks, in a transaction of its own."""
    runtime = client.app.state.runtime

    def write() -> None:
        with runtime.sessions() as session, writing(session):
            emit(session, owner=Owner("study", study_id), type_="test", subject=None, data=dict)

    return write


def in_all(open_now: dict[str, int]) -> int:
    return sum(open_now.values())


def test_a_stalled_receiver_never_delays_a_fast_one(
    client: TestClient, study: dict[str, Any]
) -> None:
    """Each event is written once the stalled receiver holds an attempt (it keeps one for the
    whole test: one of its events, then the next when an attempt times out), and must reach
    the fast receiver within 1 s of its own timestamp."""
    write = emitter(client, study["id"])
    with StalledReceiver() as stalled, Receiver() as fast:
        slow_hook = register(client, stalled.url(), study["id"])
        fast_hook = register(client, fast.url(), study["id"])
        write()
        wait_for(stalled.open_now, what="the stalled receiver holding an attempt")
        for n in range(1, 11):
            if n > 1:
                write()
            wait_for(fast.received, lambda got, n=n: len(got) >= n, what=f"event {n} fast")
        lags = [delivery.lag_s for delivery in fast.received()]
        sent = {e["event_id"] for e in events(client, fast_hook["id"])}
        assert fast.event_ids() == sent and len(fast.received()) == 10
    remove(client, slow_hook, fast_hook)
    assert max(lags) < MAX_LAG_S, [round(lag, 3) for lag in lags]
    assert stalled.peak_per_path == 1  # one attempt at a time for the stalled webhook


def test_attempts_in_flight_are_one_per_webhook_and_bounded_in_all(
    client: TestClient, study: dict[str, Any]
) -> None:
    """Three stalled receivers with two events each and two lanes: two hold an attempt, the
    third waits until one of the two hangs up; never more than two at once, nor two for one
    webhook."""
    write = emitter(client, study["id"])
    with StalledReceiver() as stalled:
        hooks = [register(client, stalled.url(f"/{name}"), study["id"]) for name in "abc"]
        write()
        write()
        held = wait_for(
            stalled.open_now, lambda now: in_all(now) == LANES, what="both lanes stalled"
        )
        [waiting] = {"/a", "/b", "/c"} - set(held)
        stalled.release(next(iter(held)))
        wait_for(
            stalled.open_now,
            lambda now: waiting in now and in_all(now) == LANES,
            what=f"{waiting} in the freed lane",
        )
        peaks = (stalled.peak_in_all, stalled.peak_per_path)
    remove(client, *hooks)
    assert peaks == (LANES, 1)


def test_stopping_cuts_attempts_short_and_leaves_no_thread(
    client: TestClient, study: dict[str, Any]
) -> None:
    """A second delivery loop beside the app's, both full (four stalled webhooks, two lanes
    each), stops at once: its two attempts end, are logged as stopped and are due again; none
    of its threads is left."""
    runtime, write = client.app.state.runtime, emitter(client, study["id"])
    with StalledReceiver() as stalled:
        hooks = [register(client, stalled.url(f"/{n}"), study["id"]) for n in range(4)]
        loop = DeliveryThread(Deliverer(runtime.sessions, Policy.of(runtime.settings))).start()
        write()
        wait_for(stalled.open_now, lambda now: in_all(now) == 2 * LANES, what="four attempts")
        started = time.monotonic()
        loop.stop()
        took = time.monotonic() - started
        alive = loop.threads()
        wait_for(stalled.open_now, lambda now: in_all(now) == LANES, what="two attempts left")
        logged = [a for hook in hooks for a in attempts(client, hook["id"])]
        outbox = {e["event_id"]: e for hook in hooks for e in events(client, hook["id"])}
    remove(client, *hooks)
    assert took < 5.0 and alive == []  # not the attempts' 10 s deadline
    stopped = [a for a in logged if a["error"] == "stopped: delivery shut down during the attempt"]
    assert len(stopped) == LANES
    for attempt in stopped:  # due again at once, for the next process
        event = outbox[attempt["event_id"]]
        assert (event["status"], event["next_attempt_at"]) == ("pending", attempt["attempted_at"])


def test_each_event_carries_its_timestamp_and_sequence_number(
    client: TestClient, study: dict[str, Any]
) -> None:
    """Eight writers at once, five events each: every event has a number of its own, the
    same for both webhooks of the study, the numbers consecutive."""
    write = emitter(client, study["id"])
    start = threading.Barrier(8)

    def writer() -> None:
        start.wait()
        for _ in range(5):
            write()

    with Receiver() as receiver:
        hooks = [register(client, receiver.url(f"/{n}"), study["id"]) for n in range(2)]
        threads = [threading.Thread(target=writer) for _ in range(8)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        numbers = [
            sorted(e["payload"]["seq"] for e in events(client, hook["id"])) for hook in hooks
        ]
        payloads = [e["payload"] for e in events(client, hooks[0]["id"])]
    remove(client, *hooks)
    assert numbers[0] == numbers[1] == list(range(numbers[0][0], numbers[0][0] + 40))
    assert all(set(p) == {"type", "timestamp", "seq", "data"} for p in payloads)
