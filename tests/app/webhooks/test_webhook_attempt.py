"""One delivery attempt is over within its deadline, whatever the receiver does
(``app/webhooks/delivery.py``): httpx bounds each read, not the whole answer, so a receiver
that trickles its headers a byte at a time must not hold the delivery loop."""

from __future__ import annotations

import re
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
            _read_request(conn)  # all of it: unread bytes would make the close a reset
            conn.sendall(b"HTTP/1.1 200 OK\r\nX-Slow: ")
            for _ in range(round(for_s / every_s)):
                if stop.wait(every_s):
                    return
                try:
                    conn.sendall(b"z")
                except OSError:  # the client gave up: that is what the test waits for
                    return
            conn.sendall(b"\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.getsockname()[1]}/hook"
    finally:
        stop.set()
        thread.join(timeout=5)
        server.close()


def _read_request(conn: socket.socket) -> None:
    """Read the request's head and its ``Content-Length`` body."""
    data = b""
    while b"\r\n\r\n" not in data:
        data += conn.recv(65536)
    head, _, body = data.partition(b"\r\n\r\n")
    length = int(re.search(rb"content-length: *(\d+)", head, re.I)[1])
    while len(body) < length:
        body += conn.recv(65536)


def _event(url: str) -> Outgoing:
    return Outgoing(1, "msg_slow", 0, {"type": "test"}, url, new_secret())


def test_httpx_timeouts_alone_let_a_trickling_receiver_hold_an_attempt() -> None:
    """Why the deadline exists: each byte comes within httpx's 5 s read timeout, so a 6 s
    trickle (longer than that timeout) still ends in a 200 when the deadline is longer."""
    with trickling_receiver(every_s=0.2, for_s=6) as url:
        outcome = post(_event(url), targets="loopback", deadline_s=60.0)
    assert outcome.status_code == 200 and outcome.duration_ms >= 6000


def test_a_receiver_trickling_its_headers_cannot_hold_an_attempt() -> None:
    """With the deadline the same kind of receiver (trickling for 30 s) is cut off."""
    with trickling_receiver(every_s=0.2, for_s=30) as url:
        outcome = post(_event(url), targets="loopback", deadline_s=1.0)
    assert outcome.status_code is None and outcome.error == "no answer within 1 s"


def test_a_receiver_that_answers_is_delivered_within_the_deadline() -> None:
    with Receiver() as receiver:
        outcome = post(_event(receiver.url()), targets="loopback", deadline_s=5.0)
    assert outcome.delivered and [d.event_id for d in receiver.received()] == ["msg_slow"]
