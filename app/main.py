"""The FastAPI application factory.

``create_app(settings)`` builds an app on an existing database (``acv serve`` applies the
migrations first). ``acv serve --workers N`` runs N of them, built by
:func:`app.cli.serve.worker_app` without the background work (the run worker, resuming
study preparation and delivering webhooks), which its supervisor process does once.
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from contextlib import AbstractAsyncContextManager, asynccontextmanager

import anyio.to_thread
from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from starlette.middleware.gzip import GZipMiddleware
from uvicorn.middleware.proxy_headers import ProxyHeadersMiddleware

from app.core.resources import STATIC_DIR
from app.http import errors, health
from app.http.access_log import install_access_log_filter
from app.http.credentials_first import CredentialsFirst
from app.http.docs import docs_router
from app.http.lockouts import DatabaseFailures
from app.http.ratelimit import (
    FAILED_LOGINS_PER_MINUTE,
    JOINS_PER_MINUTE,
    OPEN_LINK_JOINS,
    LoginLimiter,
)
from app.jobs.worker import start_app_worker
from app.middleware import BodySizeLimit, SecurityHeaders
from app.routes import api_router, pages_router
from app.runtime import Runtime
from app.settings import Settings
from app.webhooks.scheduler import start_delivery
from engine import __version__

#: Where the OpenAPI document is served (``/docs`` reads it).
OPENAPI_URL = "/openapi.json"


def create_app(
    settings: Settings | None = None, *, background: bool = True, processes: int = 1
) -> FastAPI:
    """The web app: REST API under ``/api``, ``/healthz``, pages, and ``/static``.

    Args:
        settings: defaults to the environment's (:class:`Settings`).
        background: run the training-run worker and resume half-prepared studies (one
            process of several serves without them).
        processes: server processes sharing the database (sizes the connection pool).
    """
    runtime = Runtime(settings or Settings(), processes=processes)
    # The docs page is ours (self-hosted Swagger UI, strict policy); no ReDoc.
    app = FastAPI(
        title="ACV",
        version=__version__,
        lifespan=_lifespan(runtime, background=background),
        docs_url=None,
        redoc_url=None,
        openapi_url=OPENAPI_URL,
        description="Advice Conformance Verification: studies, invite links and bracket labelling.",
    )
    app.state.runtime = runtime
    _install_limiters(app, runtime, processes)
    install_access_log_filter()  # invite tokens in /p/<token> paths
    _add_middleware(app, runtime)
    errors.install(app)
    _mount_routes(app)
    return app


def _lifespan(
    runtime: Runtime, *, background: bool
) -> Callable[[FastAPI], AbstractAsyncContextManager[None]]:
    """Start-up and shut-down: thread limit, half-prepared studies, the run worker, webhook
    delivery."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # Few worker threads: requests are short and SQLite takes one writer at a time, so
        # more threads only fight over the GIL (a lock convoy that multiplies tail latency).
        anyio.to_thread.current_default_thread_limiter().total_tokens = runtime.settings.threads
        run_worker = webhooks = None
        if background:
            runtime.resume()  # studies a previous process left half-prepared
            run_worker = start_app_worker(app)  # training runs, unless ACV_RUN_WORKER=0
            webhooks = start_delivery(runtime.sessions, runtime.settings)  # the outbox
        try:
            yield
        finally:
            if webhooks is not None:
                await anyio.to_thread.run_sync(webhooks.stop)
            if run_worker is not None:
                # Running runs checkpoint and become `interrupted`; the loop stays responsive.
                await anyio.to_thread.run_sync(run_worker.stop)
            runtime.close()

    return lifespan


def _install_limiters(app: FastAPI, runtime: Runtime, processes: int) -> None:
    """Failed researcher logins, counted in the database by every process and host; and new
    people per address through open links, which ``acv serve --workers N``'s processes count
    together in a file of the data dir."""
    failures = DatabaseFailures(runtime.engine, FAILED_LOGINS_PER_MINUTE)
    app.state.login_limiter = LoginLimiter(FAILED_LOGINS_PER_MINUTE, store=failures)
    shared = runtime.settings.data_dir if processes > 1 else None
    app.state.join_limiter = LoginLimiter(
        JOINS_PER_MINUTE, shared=shared / OPEN_LINK_JOINS if shared else None
    )


def _add_middleware(app: FastAPI, runtime: Runtime) -> None:
    """The middleware stack, innermost first."""
    # Credentials are checked before the body is parsed; an oversized one is refused first,
    # by its declared length, unread.
    app.add_middleware(CredentialsFirst)
    app.add_middleware(BodySizeLimit)
    app.add_middleware(SecurityHeaders)  # 413 answers get the headers too
    if runtime.settings.trusted_proxies:
        # Outermost: the client address every limit is keyed by is the forwarded one, and
        # only from the named proxies. The servers we start leave the headers alone
        # (``proxy_headers=False``): uvicorn's default trusts 127.0.0.1.
        app.add_middleware(ProxyHeadersMiddleware, trusted_hosts=runtime.settings.trusted_proxies)


def _mount_routes(app: FastAPI) -> None:
    """``/healthz``, ``/docs``, the API, the pages and ``/static``."""
    app.include_router(health.router)
    app.include_router(docs_router(openapi_url=OPENAPI_URL, title=f"{app.title} API"))
    app.include_router(api_router)
    app.include_router(pages_router)
    # gzip for the static files only (the vendored d3 and Plot builds shrink about 3x);
    # the API's small JSON answers stay uncompressed on the hot path
    app.mount(
        "/static",
        GZipMiddleware(StaticFiles(directory=STATIC_DIR), minimum_size=1024),
        name="static",
    )
