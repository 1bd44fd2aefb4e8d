"""Webhook receivers on 127.0.0.1 (tests send traffic nowhere else): one that records every
delivery and when it arrived, and one that never answers; the signature check of the
``standardwebhooks`` package, and reading a webhook's events and attempts through the API."""

from __future__ import annotations

import json
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import TYPE_CHECKING, Any

from standardwebhooks import Webhook as Verifier

if TYPE_CHECKING:
    from app.settings import Settings

from tests.support.web import ADMIN, ADMIN_TOKEN


@dataclass(frozen=True)
class Delivery:
    """One POST the receiver got."""

    path: str
    headers: dict[str, str]
    body: bytes
    #: When it arrived (Unix seconds).
    received_at: float

    @property
    def event_id(self) -> str:
        return self.headers["webhook-id"]

    @property
    def payload(self) -> dict[str, Any]:
        return json.loads(self.body)

    @property
    def lag_s(self) -> float:
        """Seconds from the event's ``timestamp`` (when it was written) to its arrival."""
        return self.received_at - datetime.fromisoformat(self.payload["timestamp"]).timestamp()

    def verified(self, secret: str) -> dict[str, Any]:
        """The payload, once the ``standardwebhooks`` package accepts the signature."""
        return Verifier(secret).verify(self.body, self.headers)


def _reserve(port: int) -> socket.socket:
    """A socket bound to ``127.0.0.1:port`` (0: any free port), not listening."""
    held = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    held.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    held.bind(("127.0.0.1", port))
    return held


class Receiver:
    """An HTTP server on ``127.0.0.1:port`` (a free one by default) answering ``status`` to
    every POST and recording it. Use as a context manager: it listens inside only."""

    def __init__(self, port: int | None = None, status: int = 200) -> None:
        # The port is held from the start by a bound socket that does not listen (a
        # connection to it is refused, as to a receiver that is down), so that no other
        # test's server can take it while this receiver is down.
        self._socket = _reserve(port or 0)
        self.port, self.status = self._socket.getsockname()[1], status
        self.deliveries: list[Delivery] = []
        self._lock = threading.Lock()
        self._server: ThreadingHTTPServer | None = None

    def url(self, path: str = "/hook") -> str:
        return f"http://127.0.0.1:{self.port}{path}"

    def received(self) -> list[Delivery]:
        with self._lock:
            return list(self.deliveries)

    def event_ids(self) -> set[str]:
        return {d.event_id for d in self.received()}

    def __enter__(self) -> Receiver:
        server = ThreadingHTTPServer(
            ("127.0.0.1", self.port), self._handler(), bind_and_activate=False
        )
        server.socket.close()
        server.socket = self._socket  # the held port, now listening
        server.server_activate()
        self._server = server
        threading.Thread(target=server.serve_forever, daemon=True).start()
        return self

    def __exit__(self, *_: object) -> None:
        assert self._server is not None
        self._server.shutdown()
        self._server.server_close()
        self._socket = _reserve(self.port)  # down again, and the port still held

    def _handler(self) -> type[BaseHTTPRequestHandler]:
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 (http.server's name)
                body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
                headers = {k.lower(): v for k, v in self.headers.items()}
                delivery = Delivery(self.path, headers, body, time.time())
                with receiver._lock:
                    receiver.deliveries.append(delivery)
                self.send_response(receiver.status)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *_args: object) -> None:
                pass

        return Handler


class StalledReceiver:
    """A receiver on 127.0.0.1 that accepts every connection, reads the request, and never
    answers until it is closed (``with`` it), or until its path is :meth:`released` (then it
    hangs up on the path's requests, at once from then on). Counts, by path, the requests the
    client keeps waiting, and the most there ever were: in all, and on one path.
    """

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self._server.settimeout(0.1)
        self.port = self._server.getsockname()[1]
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._open: Counter[str] = Counter()
        self._released: set[str] = set()
        self.peak_in_all = self.peak_per_path = self.requests = 0
        self._acceptor = threading.Thread(target=self._accept, daemon=True)
        self._threads: list[threading.Thread] = []  # one a request

    def url(self, path: str = "/stalled") -> str:
        return f"http://127.0.0.1:{self.port}{path}"

    def open_now(self) -> dict[str, int]:
        """The requests waiting now, by path."""
        with self._lock:
            return {path: n for path, n in self._open.items() if n}

    def release(self, path: str) -> None:
        """Hang up on the path's requests, those waiting and those to come."""
        with self._lock:
            self._released.add(path)

    def __enter__(self) -> StalledReceiver:
        self._acceptor.start()
        return self

    def __exit__(self, *_: object) -> None:
        self._stop.set()
        self._acceptor.join(timeout=5)  # then no request thread starts any more
        for thread in self._threads:
            thread.join(timeout=5)
        self._server.close()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            thread = threading.Thread(target=self._hold, args=(conn,), daemon=True)
            self._threads.append(thread)
            thread.start()

    def _hold(self, conn: socket.socket) -> None:
        """Read the request's head; hold the request until the client gives up, the path is
        released or the receiver closes."""
        conn.settimeout(0.1)
        with conn:
            head = self._read(conn, "", until=lambda data: b"\r\n\r\n" in data)
            if head is None:
                return
            path = head.split(b" ", 2)[1].decode()
            with self._lock:
                self.requests += 1
                self._open[path] += 1
                self.peak_per_path = max(self.peak_per_path, self._open[path])
                self.peak_in_all = max(self.peak_in_all, sum(self._open.values()))
            self._read(conn, path, until=lambda _: False)  # the body, then a hang-up
            with self._lock:
                self._open[path] -= 1

    def _read(self, conn: socket.socket, path: str, until: Callable[[bytes], bool]) -> bytes | None:
        """Read until ``until(data)``; ``None`` once the client closed, the path is released
        or the receiver stops."""
        data = b""
        while not self._stop.is_set() and path not in self._released:
            try:
                chunk = conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return None
            if not chunk:
                return None
            data += chunk
            if until(data):
                return data
        return None


def events(api: Any, webhook_id: int, headers: dict[str, str] = ADMIN) -> list[dict[str, Any]]:
    """The webhook's outbox (``GET /api/webhooks/{id}/events``) through a client of the app
    (a TestClient, or an ``httpx.Client`` on a server, with its researcher ``headers``)."""
    response = api.get(f"/api/webhooks/{webhook_id}/events", headers=headers)
    assert response.status_code == 200, response.text
    return response.json()


def attempts(api: Any, webhook_id: int, headers: dict[str, str] = ADMIN) -> list[dict[str, Any]]:
    """The webhook's delivery attempts, newest first."""
    response = api.get(f"/api/webhooks/{webhook_id}/attempts", headers=headers)
    assert response.status_code == 200, response.text
    return response.json()


def webhook_settings(backend_url: tuple[Path, str], **extra: Any) -> Settings:
    """The webhook tests' settings: webhooks to 127.0.0.1 only and quick retries (and
    ``extra``), on the test database."""
    from app.settings import Settings

    data_dir, url = backend_url
    return Settings(
        data_dir=data_dir,
        database_url=url,
        admin_token=ADMIN_TOKEN,
        webhook_targets="loopback",
        webhook_backoff_s=0.2,
        webhook_backoff_cap_s=0.4,
        **extra,
    )
