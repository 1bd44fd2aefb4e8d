"""Stimuli on disk: a window of stored states as a still (JPEG) and a clip (animated WebP).

A still is rendered exactly as the candidates are (:class:`~engine.render.RenderSpec`, JPEG,
through the :class:`~engine.render.RenderService`) and named by the render cache's key.

A clip shows every ``stride``-th env step of a window, each frame lasting ``stride × dt``
seconds, so that it plays at the speed the simulation ran (Humanoid-v5: dt = 0.015 s, at
about 15 fps stride 4 and 60 ms frames). Frames come from the product's
:class:`~engine.render.FrameRenderer` with the stills' :class:`~engine.render.RenderSpec`
(same camera, size and fast settings), so a clip's frame looks like the still of its state.

Format: animated WebP through Pillow, which the product already depends on (no new
dependency). Pillow's wheels bundle libwebp (BSD licence) for Python 3.11, and every current
phone browser plays animated WebP (Safari since iOS 14, Chrome and Firefox on Android). PyAV
(H.264 video) would need Python 3.12 wheels and bundles GPL codecs. Clips loop forever.

Files are content-addressed like the render cache (``<key[:2]>/<key>.webp``): the key hashes
the env id, every frame's state, the render settings and the timing, so the same clip is never
rendered twice and its name says nothing of the run it came from.
"""

from __future__ import annotations

import hashlib
import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from PIL import Image

from engine.gym_types import box, mujoco_base
from engine.render import FrameRenderer, RenderCache, RenderService, RenderSpec, cache_key
from engine.render.cache import RENDER_VERSION, write_atomically
from engine.render.service import get_render_service
from engine.render.views import VIEWS

if TYPE_CHECKING:  # mujoco loads where an env is built
    from gymnasium.envs.mujoco.mujoco_env import MujocoEnv

#: Part of every clip key: bump it when the clip encoding changes.
CLIP_VERSION = 1
CLIP_FORMAT = "webp"
CLIP_MEDIA_TYPE = "image/webp"
#: libwebp's lossy quality: clips 17% smaller than at Pillow's default 80 (Humanoid, 480 px).
WEBP_QUALITY = 70
#: libwebp's effort, 0 (fast) .. 6: its default; 2 saves half the CPU for 5% more bytes.
WEBP_METHOD = 4
#: Observation -> action (clipped here to the action space), as the judges' policies.
Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class Window:
    """The frames of one stimulus.

    Attributes:
        index: its place among the run's windows.
        qpos: each frame's positions, shape ``(F, nq)``, one every ``stride`` env steps.
        qvel: each frame's velocities, shape ``(F, nv)``.
        frame_ms: how long each frame shows: ``stride × dt`` in milliseconds (real time).
        still_frame: the frame shown as the still (the middle one: ``F // 2``).
        start: the episode step of its first frame (0: the state after the first step).
    """

    index: int
    qpos: np.ndarray
    qvel: np.ndarray
    frame_ms: float
    still_frame: int
    start: int


@dataclass(frozen=True)
class Stimulus:
    """One window's files, paths relative to the stimuli folder.

    Attributes:
        window: the window's index.
        still: the still's JPEG.
        clip: the clip's animated WebP, or None where clips are off.
        n_frames: frames in the window (libwebp merges a frame identical to the one before
            it into that one, adding up their durations: the file may hold fewer).
        frame_duration_ms: each frame's duration (``stride × dt``, real time).
        still_bytes: the still's size in bytes.
        clip_bytes: the clip's size in bytes, or None without a clip.
    """

    window: int
    still: str
    clip: str | None
    n_frames: int
    frame_duration_ms: float
    still_bytes: int
    clip_bytes: int | None


def step_dt(env: gym.Env[Any, Any]) -> float:
    """Seconds of simulation per env step: the MuJoCo timestep times the frame skip
    (Humanoid-v5: 0.003 × 5 = 0.015)."""
    return float(cast("MujocoEnv", env.unwrapped).dt)


def frame_stride(dt: float, fps: float) -> int:
    """Env steps between clip frames: the whole number nearest ``1 / (fps × dt)``, at least 1
    (Humanoid-v5 at 15 fps: 4 steps, 60 ms a frame)."""
    return max(1, round(1.0 / (fps * dt)))


def clip_frames(dt: float, stride: int, clip_s: float) -> int:
    """Frames in a clip of ``clip_s`` seconds (at least 1): 33 for 2 s of Humanoid-v5."""
    return max(1, round(clip_s / (dt * stride)))


def window_span(dt: float, fps: float, clip_s: float) -> tuple[int, int]:
    """Env steps between a window's frames, and from its first frame to its last plus one
    (Humanoid-v5 at 15 fps for 2 s: 4 and 129, 33 frames of 60 ms)."""
    stride = frame_stride(dt, fps)
    return stride, (clip_frames(dt, stride, clip_s) - 1) * stride + 1


def frame_durations(n_frames: int, frame_ms: float) -> list[int]:
    """Whole-millisecond durations (WebP stores integers) of ``n_frames`` frames of
    ``frame_ms`` each, rounded so that the running total stays within 0.5 ms of real time."""
    ends = np.rint(np.arange(1, n_frames + 1) * frame_ms).astype(np.int64)
    return [int(d) for d in np.diff(ends, prepend=0)]


def clip_key(
    env_id: str, qpos: np.ndarray, qvel: np.ndarray, spec: RenderSpec, frame_ms: float
) -> str:
    """Hex digest naming a clip: env, frames, render settings, timing and encoder.

    Args:
        env_id: the Gymnasium env id.
        qpos: each frame's generalised positions, shape ``(F, nq)``; hashed as float64.
        qvel: each frame's generalised velocities, shape ``(F, nv)``.
        spec: the render settings (the view's camera parameters are hashed, not its name).
        frame_ms: how long each frame shows, in milliseconds.
    """
    h = hashlib.blake2b(digest_size=20)
    header = (
        f"acv-clip/{CLIP_VERSION}/{RENDER_VERSION}|{env_id}|{VIEWS[spec.view]}|{spec.size}|"
        f"{spec.quality}|{frame_ms!r}|{WEBP_QUALITY}|{WEBP_METHOD}|{np.shape(qpos)}|"
        f"{np.shape(qvel)}"
    )
    h.update(header.encode())
    for values in (qpos, qvel):
        h.update(np.ascontiguousarray(values, dtype="<f8").tobytes())
    return h.hexdigest()


def frame_image(pixels: np.ndarray, size: int) -> Image.Image:
    """A rendered frame, shape ``(k * size, k * size, 3)``, shrunk to ``size`` pixels as the
    stills are (box filter for the supersampling factor ``k``)."""
    image = Image.fromarray(pixels)
    factor = image.width // size
    return image.reduce(factor) if factor > 1 else image


def encode_clip(frames: Sequence[Image.Image], frame_ms: float) -> bytes:
    """Animated WebP of ``frames`` (at least one), each shown ``frame_ms``, looping forever."""
    out = io.BytesIO()
    frames[0].save(
        out,
        format="WEBP",
        save_all=True,
        append_images=list(frames[1:]),
        duration=frame_durations(len(frames), frame_ms),
        loop=0,
        quality=WEBP_QUALITY,
        method=WEBP_METHOD,
    )
    return out.getvalue()


#: One clip's states: ``qpos`` of shape ``(F, nq)`` and ``qvel`` of shape ``(F, nv)``.
ClipStates = tuple[np.ndarray, np.ndarray]


def render_windows(
    env_id: str,
    windows: Sequence[Window],
    spec: RenderSpec,
    out_dir: Path,
    *,
    clips: bool,
    service: RenderService | None = None,
) -> list[Stimulus]:
    """Each window's still, and its clip where ``clips``, stored under ``out_dir`` unless
    there already: stills through ``service`` (the process-wide one by default), clips on the
    calling thread (:func:`render_clips`).

    Raises:
        InputError: unknown env, or states that do not fit it.
        BackendError: no off-screen OpenGL backend works.
    """
    cache = RenderCache(out_dir)
    stills = render_stills(env_id, windows, spec, cache, service)
    found: list[Path | None] = [None] * len(windows)
    if clips and windows:  # the windows of one env share their frame time
        states = [(w.qpos, w.qvel) for w in windows]
        found = list(render_clips(env_id, states, spec, windows[0].frame_ms, cache))
    out = Path(out_dir)
    return [_stimulus(w, s, c, out) for w, s, c in zip(windows, stills, found, strict=True)]


def render_stills(
    env_id: str,
    windows: Sequence[Window],
    spec: RenderSpec,
    cache: RenderCache,
    service: RenderService | None = None,
) -> list[Path]:
    """Each window's still (its ``still_frame``) in ``cache``, rendered only where missing."""
    states = [(w.qpos[w.still_frame], w.qvel[w.still_frame]) for w in windows]
    paths = [cache.path(cache_key(env_id, q, v, spec), spec.fmt) for q, v in states]
    missing = [(p, s) for p, s in zip(paths, states, strict=True) if not p.exists()]
    if missing:
        renderer = service if service is not None else get_render_service()
        images = renderer.iter_render(env_id, [s for _, s in missing], spec)
        for (path, _), data in zip(missing, images, strict=True):
            write_atomically(path, data)
    return paths


def _stimulus(window: Window, still: Path, clip: Path | None, out_dir: Path) -> Stimulus:
    def rel(path: Path) -> str:
        return path.relative_to(out_dir).as_posix()

    return Stimulus(
        window=window.index,
        still=rel(still),
        clip=None if clip is None else rel(clip),
        n_frames=len(window.qpos),
        frame_duration_ms=window.frame_ms,
        still_bytes=still.stat().st_size,
        clip_bytes=None if clip is None else clip.stat().st_size,
    )


def render_clips(
    env_id: str, clips: Sequence[ClipStates], spec: RenderSpec, frame_ms: float, cache: RenderCache
) -> list[Path]:
    """Each clip's WebP file in ``cache``, rendered only where it is not stored yet.

    Renders on the calling thread with a :class:`~engine.render.FrameRenderer` of its own,
    made only when something is missing and closed before returning (its GL context belongs
    to this thread): call it from a background thread, never from a request.

    Raises:
        InputError: unknown env, or states that do not fit it.
        BackendError: no off-screen OpenGL backend works.
    """
    paths = [cache.path(clip_key(env_id, q, v, spec, frame_ms), CLIP_FORMAT) for q, v in clips]
    missing = [(p, c) for p, c in zip(paths, clips, strict=True) if not p.exists()]
    if missing:
        renderer = FrameRenderer()
        try:
            for path, (qpos, qvel) in missing:
                frames = [
                    frame_image(renderer.frame(env_id, q, v, spec), spec.size)
                    for q, v in zip(qpos, qvel, strict=True)
                ]
                write_atomically(path, encode_clip(frames, frame_ms))
        finally:
            renderer.close()
    return paths


def roll_forward(
    env: gym.Env[Any, Any], policy: Policy, obs: np.ndarray, max_steps: int
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Step ``env`` under ``policy`` from observation ``obs`` (its current state).

    Returns:
        ``qpos`` of shape ``(T, nq)`` and ``qvel`` of shape ``(T, nv)`` after each step, and
        whether the episode ended (terminated or truncated); ``T = max_steps`` unless it did.
    """
    space, data = box(env.action_space), mujoco_base(env).data
    qpos: list[np.ndarray] = []
    qvel: list[np.ndarray] = []
    ended = False
    while len(qpos) < max_steps and not ended:
        obs, _, terminated, truncated, _ = env.step(policy(obs).clip(space.low, space.high))
        qpos.append(data.qpos.copy())
        qvel.append(data.qvel.copy())
        ended = bool(terminated or truncated)
    model = mujoco_base(env).model
    return _stack(qpos, model.nq), _stack(qvel, model.nv), ended


def _stack(rows: list[np.ndarray], width: int) -> np.ndarray:
    return np.stack(rows) if rows else np.zeros((0, width))
