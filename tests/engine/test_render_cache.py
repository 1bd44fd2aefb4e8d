"""The content-addressed render cache: keys, atomic writes across threads and processes."""

from __future__ import annotations

import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from engine.render import RenderCache, RenderSpec, cache_key

QPOS, QVEL = np.linspace(-1.0, 1.0, 24), np.linspace(0.0, 2.0, 23)
BASE = ("Humanoid-v5", QPOS, QVEL, RenderSpec())


def nudge(a: np.ndarray) -> np.ndarray:
    b = a.copy()
    b[3] = np.nextafter(b[3], np.inf)
    return b


@pytest.mark.parametrize(
    "changed",
    [
        ("Hopper-v5", QPOS, QVEL, RenderSpec()),
        ("Humanoid-v5", nudge(QPOS), QVEL, RenderSpec()),
        ("Humanoid-v5", QPOS, nudge(QVEL), RenderSpec()),
        ("Humanoid-v5", QPOS, QVEL, RenderSpec(view="front")),
        ("Humanoid-v5", QPOS, QVEL, RenderSpec(size=481)),
        ("Humanoid-v5", QPOS, QVEL, RenderSpec(fmt="png")),
        ("Humanoid-v5", QPOS, QVEL, RenderSpec(quality=True)),
        ("Humanoid-v5", np.append(QPOS, QVEL[0]), QVEL[1:], RenderSpec()),  # same bytes, new split
    ],
)
def test_key_changes_with_anything_the_image_depends_on(changed: tuple) -> None:
    assert cache_key(*changed) != cache_key(*BASE)


def test_key_ignores_representation() -> None:
    same = ("Humanoid-v5", list(QPOS), QVEL.astype(">f8"), RenderSpec(fmt="JPEG"))
    assert cache_key(*same) == cache_key(*BASE)


def test_put_then_get(tmp_path: Path) -> None:
    cache = RenderCache(tmp_path / "renders")
    key = cache_key(*BASE)
    assert cache.get(key, "jpg") is None
    path = cache.put(key, "jpg", b"image bytes")
    assert path.name == f"{key}.jpg" and cache.get(key, "jpg") == b"image bytes"


def test_concurrent_writers_never_expose_partial_files(tmp_path: Path) -> None:
    cache, key = RenderCache(tmp_path), cache_key(*BASE)
    payloads = [bytes([i]) * 300_000 for i in range(4)]
    seen: list[bytes | None] = []
    done = threading.Event()

    def read_until_done() -> None:
        while not done.is_set():
            seen.append(cache.get(key, "png"))

    reader = threading.Thread(target=read_until_done)
    reader.start()
    with ThreadPoolExecutor(max_workers=4) as pool:
        list(pool.map(lambda p: [cache.put(key, "png", p) for _ in range(20)], payloads))
    done.set()
    reader.join()
    assert all(s is None or s in payloads for s in seen)
    assert cache.get(key, "png") in payloads
    assert [p.name for p in tmp_path.rglob("*")] == [key[:2], f"{key}.png"]


WRITER = """
import sys
from engine.render.cache import RenderCache
cache = RenderCache(sys.argv[1])
for _ in range(40):
    cache.put(sys.argv[2], "jpg", sys.argv[3].encode() * 500_000)
"""


@pytest.mark.process
def test_two_processes_writing_the_same_entry(tmp_path: Path) -> None:
    key = cache_key(*BASE)
    writers = [
        subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), key, tag])
        for tag in ("a", "b")
    ]
    cache, whole = RenderCache(tmp_path), (b"a" * 500_000, b"b" * 500_000)
    while any(w.poll() is None for w in writers):
        data = cache.get(key, "jpg")
        assert data is None or data in whole
    assert [w.wait() for w in writers] == [0, 0]
    assert cache.get(key, "jpg") in whole
    assert not list(tmp_path.rglob("*.tmp"))
