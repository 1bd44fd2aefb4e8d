"""Candidate images: rendered once when a study is prepared, stored under the data dir.

Images live in a content-addressed :class:`~engine.render.RenderCache` inside
``ACV_DATA_DIR/images``; the database keeps each candidate's paths relative to the data dir.
Clients only ever name a study and a candidate id; no path from a request is opened.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from app.core.errors import NotFoundError
from engine.candidates import Candidate
from engine.render import RenderCache, RenderService, RenderSpec, cache_key

ImageSize = Literal["full", "thumb"]
SPECS: dict[ImageSize, RenderSpec] = {"full": RenderSpec(), "thumb": RenderSpec.thumbnail()}
MEDIA_TYPE = SPECS["full"].media_type


def render_candidates(
    renderer: RenderService, *, data_dir: Path, env_id: str, candidates: Sequence[Candidate]
) -> list[dict[ImageSize, str]]:
    """Render every candidate at both sizes; returns their paths relative to ``data_dir``.

    Raises:
        RuntimeError: the renderer has no cache under ``data_dir`` to store images in.
    """
    cache = renderer.cache
    if cache is None or not cache.root.resolve().is_relative_to(data_dir.resolve()):
        raise RuntimeError("the render service must cache its images inside the data dir")
    states = [(c.qpos, c.qvel) for c in candidates]
    paths: list[dict[ImageSize, str]] = [{} for _ in candidates]
    for size, spec in SPECS.items():
        images = renderer.iter_render(env_id, states, spec)
        for out, (qpos, qvel), data in zip(paths, states, images, strict=True):
            out[size] = _store(cache, data_dir, cache_key(env_id, qpos, qvel, spec), spec, data)
    return paths


def _store(cache: RenderCache, data_dir: Path, key: str, spec: RenderSpec, data: bytes) -> str:
    path = cache.path(key, spec.fmt)
    if not path.exists():  # the service normally wrote it already
        path = cache.put(key, spec.fmt, data)
    return path.resolve().relative_to(data_dir.resolve()).as_posix()


def image_file(data_dir: Path, stored_path: str) -> Path:
    """The file of a stored image path, refusing anything outside the data dir.

    Raises:
        NotFoundError: the path (after symlinks) leads out of the data dir.
    """
    root = data_dir.resolve()
    path = (root / stored_path).resolve()
    if not path.is_relative_to(root):
        raise NotFoundError("the image file is not in the data dir")
    return path
