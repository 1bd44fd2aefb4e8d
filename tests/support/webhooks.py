"""A webhook receiver on 127.0.0.1 that records every delivery (tests send traffic nowhere
else), the signature check of the ``standardwebhooks`` package, and reading a webhook's
events and attempts through the API."""

from __future__ import annotations

import json
import socket
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from standardwebhooks import Webhook as Verifier

from tests.support.web import ADMIN


@dataclass(frozen=True)
class Delivery:
    """One POST the receiver got."""

    path: str
    headers: dict[str, str]
    body: bytes

    @property
    def event_id(self) -> str:
        return self.headers["webhook-id"]

    @property
    def payload(self) -> dict[str, Any]:
        return json.loads(self.body)

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
                with receiver._lock:
                    receiver.deliveries.append(Delivery(self.path, headers, body))
                self.send_response(receiver.status)
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *_args: object) -> None:
                pass

        return Handler


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
