"""A local stand-in for the Hugging Face Hub, on 127.0.0.1: enough of its HTTP API for
``huggingface_hub``'s ``create_repo`` and ``upload_folder`` (``HF_ENDPOINT`` points at it).

It answers every file's pre-upload as a ``regular`` file, so the files come inline (base64)
in the commit's NDJSON body rather than through LFS or Xet storage, and keeps each repository
as it was created and the files each commit added, with the token every request carried.
"""

from __future__ import annotations

import base64
import json
import re
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import yaml

_REPO = r"(?P<repo>[^/]+/[^/]+)"
_PREUPLOAD = re.compile(rf"/api/datasets/{_REPO}/preupload/(?P<rev>[^/?]+)")
_COMMIT = re.compile(rf"/api/datasets/{_REPO}/commit/(?P<rev>[^/?]+)")


@dataclass
class Hub:
    """What the stand-in was asked: repositories made, files committed, requests seen."""

    url: str = ""
    repos: dict[str, dict[str, Any]] = field(default_factory=dict)
    files: dict[str, dict[str, bytes]] = field(default_factory=dict)
    requests: list[tuple[str, str, str | None]] = field(default_factory=list)
    metadata: list[dict[str, Any]] = field(default_factory=list)
    commits: int = 0


def _handler(hub: Hub) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def do_POST(self) -> None:  # noqa: N802 (http.server's name)
            body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
            hub.requests.append(("POST", self.path, self.headers.get("Authorization")))
            if self.path.startswith("/api/repos/create"):
                made = json.loads(body)
                repo = f"{made['organization']}/{made['name']}" if "organization" in made else ""
                repo = repo or made["name"]
                hub.repos[repo] = made
                return self._json({"url": f"{hub.url}/datasets/{repo}", "name": repo})
            if self.path.startswith("/api/validate-yaml"):
                return self._validate(json.loads(body)["content"])
            if match := _PREUPLOAD.match(self.path):
                files = json.loads(body)["files"]
                regular = [
                    {"path": f["path"], "uploadMode": "regular", "shouldIgnore": False}
                    for f in files
                ]
                return self._json({"files": regular, "commitOid": None})
            if match := _COMMIT.match(self.path):
                return self._commit(match["repo"], body)
            self._json({"error": f"not in the stand-in: POST {self.path}"}, 404)

        def do_GET(self) -> None:  # noqa: N802
            hub.requests.append(("GET", self.path, self.headers.get("Authorization")))
            self._json({"error": f"not in the stand-in: GET {self.path}"}, 404)

        def _validate(self, readme: str) -> None:
            """The card's YAML metadata must parse to a mapping (the Hub checks far more)."""
            head = readme.split("---\n")
            try:
                meta = yaml.safe_load(head[1]) if readme.startswith("---\n") else None
            except yaml.YAMLError as exc:
                meta = str(exc)
            if not isinstance(meta, dict):
                return self._json({"errors": [{"message": f"bad metadata: {meta!r}"}]}, 400)
            hub.metadata.append(meta)
            self._json({"errors": [], "warnings": []})

        def _commit(self, repo: str, body: bytes) -> None:
            added = hub.files.setdefault(repo, {})
            for line in body.decode().splitlines():
                item = json.loads(line)
                if item["key"] == "file":
                    added[item["value"]["path"]] = base64.b64decode(item["value"]["content"])
            hub.commits += 1
            oid = f"{hub.commits:040x}"
            url = f"{hub.url}/datasets/{repo}/commit/{oid}"
            self._json({"commitUrl": url, "commitOid": oid, "success": True})

        def _json(self, value: Any, status: int = 200) -> None:
            data = json.dumps(value).encode()
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def log_message(self, *_args: Any) -> None:
            pass

    return Handler


@contextmanager
def local_hub() -> Iterator[Hub]:
    """Serve a :class:`Hub` stand-in on a free port of 127.0.0.1 while the block runs."""
    hub = Hub()
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), _handler(hub))
    hub.url = f"http://127.0.0.1:{httpd.server_address[1]}"
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield hub
    finally:
        httpd.shutdown()
        httpd.server_close()
