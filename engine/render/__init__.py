"""Off-screen rendering of stored states: ``(env_id, qpos, qvel)`` in, JPEG or PNG out.

Headless on CPU-only and GPU machines alike (EGL or OSMesa, see :mod:`.backend`), fast by
default, thread-safe through one render thread (:class:`RenderService`), with a
content-addressed disk cache (:class:`RenderCache`).

Example:
    >>> service = get_render_service()
    >>> jpeg = service.render("Humanoid-v5", qpos, qvel, view="side", size=480)
"""

from engine.render.backend import BackendError, activate, select_backend
from engine.render.cache import RenderCache, cache_key
from engine.render.image import encode
from engine.render.renderer import FrameRenderer
from engine.render.service import (
    RenderService,
    default_cache_dir,
    get_render_service,
    shutdown_render_service,
)
from engine.render.views import (
    DEFAULT_SIZE,
    DEFAULT_VIEW,
    FORMATS,
    MAX_SIZE,
    MIN_SIZE,
    THUMBNAIL_SIZE,
    VIEWS,
    RenderSpec,
    View,
)

__all__ = [
    "DEFAULT_SIZE",
    "DEFAULT_VIEW",
    "FORMATS",
    "MAX_SIZE",
    "MIN_SIZE",
    "THUMBNAIL_SIZE",
    "VIEWS",
    "BackendError",
    "FrameRenderer",
    "RenderCache",
    "RenderService",
    "RenderSpec",
    "View",
    "activate",
    "cache_key",
    "default_cache_dir",
    "encode",
    "get_render_service",
    "select_backend",
    "shutdown_render_service",
]
