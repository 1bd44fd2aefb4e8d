"""``acv serve`` in a subprocess on 127.0.0.1, for tests that need a real server."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx

from tests.support.net import free_port
from tests.support.wait import wait_for

REPO = Path(__file__).resolve().parents[2]
#: How long a test's HTTP call to a served app waits: on a loaded 2-core machine a fresh
#: worker importing torch can hold a request for longer than httpx's default 5 s.
HTTP_TIMEOUT_S = 60.0
#: ``acv`` as a user starts it, in a fresh interpreter.
ACV = [sys.executable, "-c", "from app.cli import main; main()"]


def clean_env(**settings: str) -> dict[str, str]:
    """This process's environment without ACV settings or a database URL, plus ``settings``
    (e.g. ``ACV_DATA_DIR``), so that a server starts from the given settings alone."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("ACV_") and k != "DATABASE_URL"}
    return env | settings


def healthy(base: str, client: httpx.Client) -> bool:
    """Whether ``base/healthz`` answers 200."""
    try:
        return client.get(f"{base}/healthz").status_code == 200
    except httpx.TransportError:
        return False


def wait_healthy(base: str, proc: subprocess.Popen, timeout_s: float = 120.0) -> None:
    """Wait until the server at ``base`` answers ``/healthz``; fail if ``proc`` exits."""

    def probe() -> bool:
        assert proc.poll() is None, f"acv serve exited with {proc.returncode}"
        return healthy(base, client)

    # One client for every probe: a new one loads the CA bundle for its TLS context each time
    # (tens of ms of CPU; 4.6% of the busy samples of a profile of a third of the suite).
    with httpx.Client(timeout=2) as client:
        wait_for(probe, what=f"acv serve at {base} to be healthy", timeout_s=timeout_s, every_s=0.2)


@contextmanager
def acv_serve(env: dict[str, str], log: Path, *args: str, cwd: Path = REPO) -> Iterator[str]:
    """``acv serve --host 127.0.0.1`` on a free port with ``env`` (and further ``args``), in
    ``cwd``, output and logs to ``log``; yields the base URL once healthy, terminates it
    after."""
    port = free_port()
    with log.open("w") as output:
        proc = subprocess.Popen(
            [*ACV, "serve", "--host", "127.0.0.1", "--port", str(port), *args],
            cwd=cwd,
            env=env,
            stdout=output,
            stderr=subprocess.STDOUT,
        )
        base = f"http://127.0.0.1:{port}"
        try:
            wait_healthy(base, proc)
            yield base
        finally:
            proc.terminate()
            proc.wait(timeout=60)
