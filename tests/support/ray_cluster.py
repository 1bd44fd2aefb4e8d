"""A real Ray cluster for a test module: one node with 2 CPUs on 127.0.0.1."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.support.net import free_port, listening
from tests.support.wait import wait_for

RAY = Path(sys.executable).with_name("ray")


def _head_up(head: subprocess.Popen, port: int) -> bool:
    assert head.poll() is None, "ray start exited"
    return listening(port)


@contextmanager
def ray_cluster() -> Iterator[str]:
    """``ray start --head --block`` in its own session and temp dir; yields its address and
    stops it with all its processes (and this process's driver, if it connected) after."""
    port, temp = free_port(), tempfile.mkdtemp(prefix="acvray")  # sockets need a short path
    # One setting for the head, its workers and the app's driver (this process): a token left
    # in ~/.ray by another cluster would otherwise switch token authentication on for some.
    saved = os.environ.get("RAY_AUTH_MODE")
    os.environ["RAY_AUTH_MODE"] = "disabled"
    env = os.environ | {"RAY_USAGE_STATS_ENABLED": "0"}
    head = subprocess.Popen(
        [
            str(RAY),
            "start",
            "--head",
            "--block",
            "--node-ip-address=127.0.0.1",
            f"--port={port}",
            "--num-cpus=2",
            "--include-dashboard=false",
            f"--dashboard-port={free_port()}",
            f"--ray-client-server-port={free_port()}",
            "--disable-usage-stats",
            f"--temp-dir={temp}",
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        wait_for(lambda: _head_up(head, port), what="Ray to start", timeout_s=90, every_s=0.2)
        yield f"127.0.0.1:{port}"
    finally:
        if "ray" in sys.modules and sys.modules["ray"].is_initialized():
            sys.modules["ray"].shutdown()  # this process's driver: the next cluster is another
        os.killpg(head.pid, signal.SIGKILL)  # the head's session: GCS, raylet, workers
        head.wait()
        shutil.rmtree(temp, ignore_errors=True)
        if saved is None:
            os.environ.pop("RAY_AUTH_MODE", None)
        else:
            os.environ["RAY_AUTH_MODE"] = saved
