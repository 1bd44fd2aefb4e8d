"""Thread-safe rendering: one dedicated render thread that any thread can submit to.

EGL contexts are bound to the thread that made them, and a web server answers requests from
a thread pool, so all OpenGL work happens on one long-lived thread owning a
:class:`~engine.render.renderer.FrameRenderer`. Callers do the rest (cache look-up, image
encoding, cache write) on their own threads, which overlaps it with the next render.
"""

from __future__ import annotations

import atexit
import logging
import os
import queue
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future
from functools import partial
from pathlib import Path
from typing import Any, cast

import numpy as np

from engine.render.cache import RenderCache, cache_key
from engine.render.image import encode
from engine.render.renderer import FrameRenderer
from engine.render.views import DEFAULT_SIZE, DEFAULT_VIEW, ImageFormat, RenderSpec

#: A stored state: ``(qpos, qvel)`` with shapes ``(nq,)`` and ``(nv,)``.
State = tuple[np.ndarray, np.ndarray]
#: Frames rendered ahead of the consumer in a batch (bounds memory at large sizes).
LOOKAHEAD = 4
_STOP = None
log = logging.getLogger(__name__)


class RenderService:
    """Renders stored states to encoded images from any thread.

    The render thread starts on first use and is stopped by :meth:`close` (also registered
    with :mod:`atexit`, so renderers are freed on their own thread, quietly, at exit).

    Args:
        cache: where to keep images by content; ``None`` renders every time.
    """

    def __init__(self, cache: RenderCache | None = None) -> None:
        self.cache = cache
        self._jobs: queue.SimpleQueue[tuple[Future[Any], Callable[[FrameRenderer], Any]] | None]
        self._jobs = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._closed = False
        self._cache_warned = False

    def render(
        self,
        env_id: str,
        qpos: np.ndarray,
        qvel: np.ndarray,
        view: str = DEFAULT_VIEW,
        size: int = DEFAULT_SIZE,
        fmt: ImageFormat = "jpg",
        quality: bool = False,
    ) -> bytes:
        """Encoded image of one state; see :class:`RenderSpec` for the options.

        Raises:
            InputError: bad options, unknown env, or a state that does not fit the env.
            BackendError: no off-screen OpenGL backend works.
        """
        spec = RenderSpec(view=view, size=size, fmt=fmt, quality=quality)
        return next(self.iter_render(env_id, [(qpos, qvel)], spec))

    def render_many(
        self,
        env_id: str,
        states: Iterable[State],
        view: str = DEFAULT_VIEW,
        size: int = DEFAULT_SIZE,
        fmt: ImageFormat = "jpg",
        quality: bool = False,
    ) -> list[bytes]:
        """Encoded images of many states of one env, in order, through one renderer."""
        spec = RenderSpec(view=view, size=size, fmt=fmt, quality=quality)
        return list(self.iter_render(env_id, states, spec))

    def iter_render(
        self, env_id: str, states: Iterable[State], spec: RenderSpec
    ) -> Iterator[bytes]:
        """Yield each state's encoded image in order (cache hits without rendering).

        Up to :data:`LOOKAHEAD` renders run ahead of the consumer; closing the iterator
        early cancels those not started.
        """
        window: deque[tuple[str, bytes | None, Future[Any] | None]] = deque()
        try:
            for qpos, qvel in states:
                window.append(self._start(env_id, qpos, qvel, spec))
                if len(window) > LOOKAHEAD:
                    yield self._finish(*window.popleft(), spec)
            while window:
                yield self._finish(*window.popleft(), spec)
        finally:
            for _, _, job in window:
                if job is not None:
                    job.cancel()

    def warm_up(
        self, env_id: str, view: str = DEFAULT_VIEW, size: int = DEFAULT_SIZE, quality: bool = False
    ) -> None:
        """Make the renderer for these settings now, so that the first request does not wait.

        Call it at web-app start-up, for example; it blocks until done.
        """
        spec = RenderSpec(view=view, size=size, quality=quality)
        self._submit(partial(FrameRenderer.warm_up, env_id=env_id, spec=spec)).result()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called; a closed service refuses new renders."""
        return self._closed

    def close(self, timeout: float = 30.0) -> None:
        """Free the renderers on the render thread and stop it. Idempotent."""
        with self._lock:
            thread, self._closed = self._thread, True
        if thread is not None and thread.is_alive():
            self._jobs.put(_STOP)
            thread.join(timeout)
        atexit.unregister(self.close)

    def __enter__(self) -> RenderService:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _start(
        self, env_id: str, qpos: np.ndarray, qvel: np.ndarray, spec: RenderSpec
    ) -> tuple[str, bytes | None, Future[Any] | None]:
        """Cache key, and either the cached image or the queued render."""
        key = cache_key(env_id, qpos, qvel, spec)
        hit = self.cache.get(key, spec.fmt) if self.cache is not None else None
        if hit is not None:
            return key, hit, None
        # Copies: the caller may reuse its arrays before the render thread reads them.
        qpos, qvel = np.array(qpos, dtype=np.float64), np.array(qvel, dtype=np.float64)
        task = partial(FrameRenderer.frame, env_id=env_id, qpos=qpos, qvel=qvel, spec=spec)
        return key, None, self._submit(task)

    def _finish(
        self, key: str, hit: bytes | None, job: Future[Any] | None, spec: RenderSpec
    ) -> bytes:
        if hit is not None:
            return hit
        data = encode(cast("Future[Any]", job).result(), spec)  # no hit: a queued render
        if self.cache is not None:
            self._store(self.cache, key, spec.fmt, data)
        return data

    def _store(self, cache: RenderCache, key: str, fmt: str, data: bytes) -> None:
        """Cache an image if possible: a cache that cannot be written only costs speed."""
        try:
            cache.put(key, fmt, data)
        except OSError as exc:
            if not self._cache_warned:  # once per service: not one line per image
                self._cache_warned = True
                log.warning(
                    "render cache %s is not writable (%s); rendering without it", cache.root, exc
                )

    def _submit(self, task: Callable[[FrameRenderer], Any]) -> Future[Any]:
        """Queue ``task(frame_renderer)`` for the render thread (started on first use)."""
        with self._lock:
            if self._closed:
                raise RuntimeError("the render service is closed")
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name="acv-render", daemon=True)
                self._thread.start()
                atexit.register(self.close)
            job: Future[Any] = Future()
            self._jobs.put((job, task))
        return job

    def _loop(self) -> None:
        frames, exit_order_fixed = FrameRenderer(), False
        try:
            while (item := self._jobs.get()) is not _STOP:
                job, task = item
                if not job.set_running_or_notify_cancel():
                    continue
                try:
                    job.set_result(task(frames))
                except BaseException as exc:  # delivered to the caller, not lost here
                    job.set_exception(exc)
                if not exit_order_fixed and frames.has_contexts:
                    # mujoco.egl registers its display teardown with atexit when it makes its
                    # first context; handlers run last-in first-out, so register again to
                    # stop rendering and free our contexts before the display goes away.
                    atexit.unregister(self.close)
                    atexit.register(self.close)
                    exit_order_fixed = True
        finally:
            frames.close()


def default_cache_dir() -> Path:
    """``$ACV_RENDER_CACHE``, else ``$XDG_CACHE_HOME/acv/renders`` (``~/.cache`` default)."""
    if explicit := os.environ.get("ACV_RENDER_CACHE"):
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "acv" / "renders"


_shared_lock = threading.Lock()
_shared: RenderService | None = None


def get_render_service() -> RenderService:
    """The process-wide service (cache in :func:`default_cache_dir`), created on first use."""
    global _shared
    with _shared_lock:
        if _shared is None or _shared.closed:
            _shared = RenderService(RenderCache(default_cache_dir()))
        return _shared


def shutdown_render_service() -> None:
    """Close the process-wide service, e.g. on web-app shutdown; a later get makes a new one."""
    global _shared
    with _shared_lock:
        service, _shared = _shared, None
    if service is not None:
        service.close()
