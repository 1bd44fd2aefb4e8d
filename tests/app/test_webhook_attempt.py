"""One delivery attempt is over within its deadline, whatever the receiver does
(``app/webhooks/delivery.py``): httpx bounds each read, not the whole answer, so a receiver
that trickles its headers a byte at a time must not hold the delivery loop."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from app.webhooks.delivery import Outgoing, post
from app.webhooks.signing import new_secret
from tests.support.webhooks import Receiver


@contextmanager
def trickling_receiver(every_s: float, for_s: float) -> Iterator[str]:
    """A receiver on 127.0.0.1 that reads a request, then sends its answer's headers one byte
    every ``every_s`` seconds for ``for_s`` seconds (each read well inside httpx's timeout),
    then a 200; yields its URL."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def answer() -> None:
        conn, _ = server.accept()
        with conn:
            conn.recv(65536)
            conn.sendall(b"HTTP/1.1 200 OK\r\nX-Slow: ")
            for _ in range(round(for_s / every_s)):
                if stop.wait(every_s):
                    return
                try:
                    conn.sendall(b"z")
                except OSError:  # the client gave up: that is what the test waits for
                    return
            conn.sendall(b"\r\nContent-Length: 0\r\n\r\n")

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.getsockname()[1]}/hook"
    finally:
        stop.set()
        thread.join(timeout=5)
        server.close()


def _event(url: str) -> Outgoing:
    return Outgoing(1, "msg_slow", 0, {"type": "test"}, url, new_secret())


def test_a_receiver_trickling_its_headers_cannot_hold_an_attempt() -> None:
    """Without the attempt's deadline this POST would end after 30 s with a 200."""
    with trickling_receiver(every_s=0.2, for_s=30) as url:
        outcome = post(_event(url), targets="loopback", deadline_s=1.0)
    assert outcome.status_code is None and outcome.error == "no answer within 1 s"


def test_a_receiver_that_answers_is_delivered_within_the_deadline() -> None:
    with Receiver() as receiver:
        outcome = post(_event(receiver.url()), targets="loopback", deadline_s=5.0)
    assert outcome.delivered and [d.event_id for d in receiver.received()] == ["msg_slow"]
