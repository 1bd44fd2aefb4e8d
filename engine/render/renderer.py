"""Stored state -> RGB frame, reusing one env and one ``mujoco.Renderer`` per setting.

A :class:`FrameRenderer` owns OpenGL contexts, and an EGL context works only on the thread
that created it: create, use and close a :class:`FrameRenderer` on one thread (the
:class:`~engine.render.service.RenderService` thread does exactly that).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np

from engine.envs import make_env, restore
from engine.gym_types import mujoco_base
from engine.render.backend import BackendError, activate, missing_backend_message
from engine.render.views import VIEWS, RenderSpec

#: Multisampling for ``quality=True`` (the Gymnasium models' own default).
FIGURE_SAMPLES = 4
#: Renderers kept per thread; each holds a GL context and a framebuffer.
MAX_RENDERERS = 8

if TYPE_CHECKING:  # mujoco loads where an env is built, not in web processes
    import mujoco

_RendererKey = tuple[str, int, bool]  # env id, pixels per side, quality


def configure(model: mujoco.MjModel, pixels: int, quality: bool) -> None:
    """Set the model's off-screen buffer and multisampling before creating a renderer.

    Gymnasium's humanoid caps the buffer at 640x480; MuJoCo reads these fields when a
    rendering context is made, so each renderer gets a buffer of exactly its own size.
    """
    model.vis.global_.offwidth = model.vis.global_.offheight = pixels
    model.vis.quality.offsamples = FIGURE_SAMPLES if quality else 0


def set_fast_flags(renderer: mujoco.Renderer, quality: bool) -> None:
    """Shadows and reflections only for figures: on CPU they cost several times the frame."""
    flags = renderer.scene.flags
    import mujoco

    flags[mujoco.mjtRndFlag.mjRND_SHADOW] = quality
    flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = quality


class FrameRenderer:
    """Renders stored states of any Gymnasium MuJoCo env; confined to one thread."""

    def __init__(self) -> None:
        self._envs: dict[str, gym.Env[Any, Any]] = {}
        self._renderers: OrderedDict[_RendererKey, mujoco.Renderer] = OrderedDict()

    def frame(
        self, env_id: str, qpos: np.ndarray, qvel: np.ndarray, spec: RenderSpec
    ) -> np.ndarray:
        """Render state ``(qpos, qvel)`` of ``env_id``.

        Returns:
            ``uint8`` RGB array of shape ``(k * spec.size, k * spec.size, 3)`` with
            ``k = spec.supersample``.

        Raises:
            InputError: unknown env id, or state shapes that do not fit the env.
            BackendError: no OpenGL context can be made.
        """
        env = self._env(env_id)
        restore(env, qpos, qvel)
        renderer = self._renderer(env_id, spec.size * spec.supersample, spec.quality)
        renderer.update_scene(mujoco_base(env).data, VIEWS[spec.view].camera())
        image: np.ndarray = renderer.render()
        return image

    def warm_up(self, env_id: str, spec: RenderSpec) -> None:
        """Make the env and renderer for ``spec`` and draw the model's initial state once.

        The first draw compiles shaders and uploads textures: about half a second on CPU.
        """
        model = mujoco_base(self._env(env_id)).model
        self.frame(env_id, model.qpos0.copy(), np.zeros(model.nv), spec)

    @property
    def has_contexts(self) -> bool:
        """Whether this holds OpenGL contexts (at least one renderer)."""
        return bool(self._renderers)

    def close(self) -> None:
        """Free every renderer and env; call it on the thread that rendered."""
        while self._renderers:
            self._renderers.popitem()[1].close()
        for env in self._envs.values():
            env.close()
        self._envs.clear()

    def _env(self, env_id: str) -> gym.Env[Any, Any]:
        if env_id not in self._envs:
            self._envs[env_id] = make_env(env_id)
        return self._envs[env_id]

    def _renderer(self, env_id: str, pixels: int, quality: bool) -> mujoco.Renderer:
        key = (env_id, pixels, quality)
        if key in self._renderers:
            self._renderers.move_to_end(key)
            return self._renderers[key]
        if len(self._renderers) >= MAX_RENDERERS:
            self._renderers.popitem(last=False)[1].close()
        model = mujoco_base(self._env(env_id)).model
        configure(model, pixels, quality)
        backend = activate()
        try:
            import mujoco

            renderer = mujoco.Renderer(model, height=pixels, width=pixels)
        except Exception as exc:  # any failure to make a context is a set-up problem
            raise BackendError(
                f"MUJOCO_GL={backend} cannot render ({type(exc).__name__}: "
                f"{exc}); {missing_backend_message()}"
            ) from exc
        set_fast_flags(renderer, quality)
        self._renderers[key] = renderer
        return renderer
