"""The FastAPI application factory.

``create_app(settings)`` builds an app on an existing database (``acv serve`` applies the
migrations first); for several workers: ``uvicorn --factory app.main:create_app``, settings
from the environment.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

import anyio.to_thread
from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from app.api import api_router, errors, health
from app.api.docs import docs_router
from app.jobs.worker import start_app_worker
from app.middleware import BodySizeLimit, SecurityHeaders
from app.runtime import Runtime
from app.settings import Settings
from app.web import router as pages_router
from app.web.access_log import install_access_log_filter
from app.web.ratelimit import LoginLimiter

STATIC_DIR = Path(__file__).resolve().parents[1] / "static"


def create_app(settings: Settings | None = None) -> FastAPI:
    """The web app: REST API under ``/api``, ``/healthz``, pages, and ``/static``.

    Args:
        settings: defaults to the environment's (:class:`Settings`).
    """
    runtime = Runtime(settings or Settings())

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        # Few worker threads: requests are short and SQLite takes one writer at a time, so
        # more threads only fight over the GIL (a lock convoy that multiplies tail latency).
        anyio.to_thread.current_default_thread_limiter().total_tokens = runtime.settings.threads
        runtime.resume()  # studies a previous process left half-prepared
        run_worker = start_app_worker(app)  # training runs (app.jobs), unless ACV_RUN_WORKER=0
        try:
            yield
        finally:
            if run_worker is not None:
                # Running runs checkpoint and become `interrupted`; the loop stays responsive.
                await anyio.to_thread.run_sync(run_worker.stop)
            runtime.close()

    # The docs page is ours (self-hosted Swagger UI, strict policy); no ReDoc.
    app = FastAPI(title="ACV", version="0.1.0", lifespan=lifespan, docs_url=None,
                  redoc_url=None,
                  description="Advice Conformance Verification: studies, invite links and "
                              "bracket labelling.")
    app.state.runtime = runtime
    app.state.login_limiter = LoginLimiter()
    install_access_log_filter()  # invite tokens in /p/<token> paths
    app.add_middleware(BodySizeLimit)
    app.add_middleware(SecurityHeaders)  # outermost: 413 answers get the headers too
    errors.install(app)
    app.include_router(health.router)
    app.include_router(docs_router(openapi_url=app.openapi_url, title=f"{app.title} API"))
    app.include_router(api_router)
    app.include_router(pages_router)
    if STATIC_DIR.is_dir():
        app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    return app
