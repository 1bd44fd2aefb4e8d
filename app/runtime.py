"""What a running app (or a CLI command) shares: settings, database, renderer, jobs.

Study preparation (sampling and rendering, a few seconds) and an evaluation's stimuli run
on one background worker thread, so ``POST /api/studies`` answers at once with status ``preparing``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TypeVar

import anyio
import anyio.to_thread
from sqlalchemy.orm import Session, sessionmaker

from app.core.auth import ensure_admin_token
from app.db import make_engine, make_sessions
from app.evaluations import service as evaluations
from app.evaluations.stimuli import prepare_evaluation
from app.jobs.settings import JobSettings
from app.preflight import check_data_dir
from app.settings import Settings
from app.studies.clips import add_clips, pending_clip_ids
from app.studies.service import prepare_study, preparing_study_ids
from engine.render import RenderCache, RenderService

log = logging.getLogger(__name__)
T = TypeVar("T")


class Runtime:
    """Engine, sessions, admin token, and the lazily started renderer and job thread.

    Args:
        settings: where the data lives and which database to use.
        processes: server processes sharing the database (sizes the connection pool).
    """

    def __init__(self, settings: Settings, *, processes: int = 1) -> None:
        check_data_dir(settings)  # fail before serving, not at the first write
        self.settings = settings
        self.engine = make_engine(settings.sqlalchemy_url, processes=processes)
        self.sessions: sessionmaker[Session] = make_sessions(self.engine)
        self.admin_token = ensure_admin_token(settings)
        self._lock = threading.Lock()
        # The participants' hot path (next match, label) runs on worker threads, at most this
        # many at once: SQLite writes one transaction at a time, and more threads than that
        # only take turns at the GIL and the write lock, so that a burst of requests queues
        # in the threads instead of in the event loop's fair queue (benchmarks/crowd_load.py).
        self.hot_path = anyio.CapacityLimiter(1 if self.engine.dialect.name == "sqlite" else 8)
        self._renderer: RenderService | None = None
        self._jobs: ThreadPoolExecutor | None = None

    @property
    def renderer(self) -> RenderService:
        """The render service, storing images in the data dir (started on first use)."""
        with self._lock:
            if self._renderer is None:
                self._renderer = RenderService(RenderCache(self.settings.images_dir))
            return self._renderer

    async def run_hot(self, func: Callable[..., T], *args: object) -> T:
        """Run ``func(*args)`` on a worker thread of the hot path (:attr:`hot_path`)."""
        return await anyio.to_thread.run_sync(func, *args, limiter=self.hot_path)

    def prepare(self, study_id: int) -> None:
        """Sample and render a study now, on this thread."""
        prepare_study(
            self.sessions,
            study_id=study_id,
            renderer=self.renderer,
            data_dir=self.settings.data_dir,
            runs_dir=JobSettings().runs_root(self.settings),
        )

    def add_clips(self, study_id: int) -> None:
        """Render a ready clips study's missing clips now, on this thread."""
        add_clips(
            self.sessions,
            study_id=study_id,
            renderer=self.renderer,
            data_dir=self.settings.data_dir,
            runs_dir=JobSettings().runs_root(self.settings),
        )

    def prepare_later(self, study_id: int) -> Future:
        """Queue a study's preparation on the background worker."""
        return self.submit(self.prepare, study_id)

    def prepare_evaluation(self, evaluation_id: int) -> None:
        """Render an evaluation's stills (then its clips) now, on this thread."""
        prepare_evaluation(
            self.sessions,
            evaluation_id=evaluation_id,
            renderer=self.renderer,
            data_dir=self.settings.data_dir,
            runs_dir=JobSettings().runs_root(self.settings),
        )

    def prepare_evaluation_later(self, evaluation_id: int) -> Future:
        """Queue an evaluation's stimuli on the background worker."""
        return self.submit(self.prepare_evaluation, evaluation_id)

    def submit(self, job: Callable[[int], None], key: int) -> Future:
        """Queue ``job(key)`` on the background worker (one thread: jobs run one at a time)."""
        with self._lock:
            if self._jobs is None:
                self._jobs = ThreadPoolExecutor(max_workers=1, thread_name_prefix="acv-jobs")
            jobs = self._jobs
        return jobs.submit(job, key)

    def resume(self) -> None:
        """Queue studies and evaluations left ``preparing`` by an earlier process."""
        with self.sessions() as session:
            study_ids = preparing_study_ids(session)
            clip_ids = pending_clip_ids(session)
            evaluation_ids = evaluations.preparing_ids(session)
        for study_id in study_ids:
            log.info("resuming preparation of study %d", study_id)
            self.prepare_later(study_id)
        for study_id in clip_ids:
            log.info("resuming the clips of study %d", study_id)
            self.submit(self.add_clips, study_id)
        for evaluation_id in evaluation_ids:
            log.info("resuming preparation of evaluation %d", evaluation_id)
            self.prepare_evaluation_later(evaluation_id)

    def close(self) -> None:
        """Finish queued jobs, stop the renderer and close database connections."""
        with self._lock:
            jobs, renderer = self._jobs, self._renderer
            self._jobs = self._renderer = None
        if jobs is not None:
            jobs.shutdown(wait=True, cancel_futures=True)
        if renderer is not None:
            renderer.close()
        self.engine.dispose()
