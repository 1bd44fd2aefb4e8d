"""Off-screen rendering of stored states: images, views, determinism, threads, cache."""

from __future__ import annotations

import io
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from engine.envs import make_env
from engine.errors import InputError
from engine.render import (
    THUMBNAIL_SIZE,
    VIEWS,
    RenderCache,
    RenderService,
    RenderSpec,
    get_render_service,
    shutdown_render_service,
)

ENV = "Humanoid-v5"
State = tuple[np.ndarray, np.ndarray]


def rollout_states(env_id: str, n: int, seed: int = 0, every: int = 15) -> list[State]:
    """``n`` distinct states from a seeded random-action rollout."""
    env = make_env(env_id)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    states = []
    while len(states) < n:
        for _ in range(every):
            env.step(env.action_space.sample())
        data = env.unwrapped.data
        states.append((data.qpos.copy(), data.qvel.copy()))
    env.close()
    return states


def decode(data: bytes) -> Image.Image:
    image = Image.open(io.BytesIO(data))
    image.load()
    return image


def robot_mask(image: Image.Image) -> np.ndarray:
    """Pixels of the robots' orange-brown bodies: the sky is blue-grey, the floor grey."""
    rgb = np.asarray(image.convert("RGB")).astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return (r > 90) & (r - b > 60) & (r - g > 30)


@pytest.fixture(scope="module")
def states() -> list[State]:
    return rollout_states(ENV, 3)


@pytest.fixture(scope="module")
def service() -> Iterator[RenderService]:
    with RenderService() as s:
        yield s


@pytest.mark.parametrize(
    ("size", "fmt", "pil_format"),
    [
        (64, "jpg", "JPEG"),
        (100, "png", "PNG"),
        (480, "jpeg", "JPEG"),
        (960, "png", "PNG"),
    ],
)
def test_image_decodes_at_requested_size_and_format(
    service: RenderService, states: list[State], size: int, fmt: str, pil_format: str
) -> None:
    image = decode(service.render(ENV, *states[0], size=size, fmt=fmt))
    assert image.format == pil_format
    assert image.size == (size, size)
    assert image.mode == "RGB"


@pytest.mark.parametrize("view", list(VIEWS))
def test_robot_is_visible_centred_and_whole(
    service: RenderService, states: list[State], view: str
) -> None:
    image = decode(service.render(ENV, *states[1], view=view, size=THUMBNAIL_SIZE, fmt="png"))
    mask = robot_mask(image)
    assert mask.mean() > 0.005, "no humanoid pixels: the image is blank or background only"
    assert not mask[: THUMBNAIL_SIZE // 10].any(), "robot colour found in the sky"
    ys, xs = np.nonzero(mask)
    assert 0.3 < xs.mean() / THUMBNAIL_SIZE < 0.7 and 0.3 < ys.mean() / THUMBNAIL_SIZE < 0.7
    margin = THUMBNAIL_SIZE // 40
    assert xs.min() > margin and ys.min() > margin
    assert xs.max() < THUMBNAIL_SIZE - margin and ys.max() < THUMBNAIL_SIZE - margin


def test_views_differ(service: RenderService, states: list[State]) -> None:
    images = {service.render(ENV, *states[0], view=v, size=64) for v in VIEWS}
    assert len(images) == len(VIEWS)


def test_same_state_same_bytes_and_different_states_differ(states: list[State]) -> None:
    with RenderService() as first, RenderService() as second:
        a, b = first.render(ENV, *states[0], size=96), first.render(ENV, *states[1], size=96)
        second.warm_up(ENV, size=96)  # draws another state first: must leave no trace
        assert second.render(ENV, *states[0], size=96) == a
    assert a != b
    diff = np.abs(np.asarray(decode(a), int) - np.asarray(decode(b), int))
    assert diff.mean() > 1.0


def test_render_many_matches_single_renders(service: RenderService, states: list[State]) -> None:
    batch = service.render_many(ENV, states, size=64, fmt="png")
    assert batch == [service.render(ENV, *s, size=64, fmt="png") for s in states]


def test_renders_from_many_threads(service: RenderService, states: list[State]) -> None:
    jobs = [states[i % len(states)] for i in range(12)]
    expected = [service.render(ENV, *s, size=48) for s in jobs]
    with ThreadPoolExecutor(max_workers=6) as pool:
        got = list(pool.map(lambda s: service.render(ENV, *s, size=48), jobs))
    assert got == expected


def test_cache_is_hit_on_second_call(tmp_path: Path, states: list[State]) -> None:
    with RenderService(RenderCache(tmp_path)) as service:
        first = service.render(ENV, *states[0], size=64)
        files = list(tmp_path.rglob("*.jpg"))
        assert len(files) == 1 and files[0].read_bytes() == first
        files[0].write_bytes(b"from the cache")  # a re-render would not return this
        assert service.render(ENV, *states[0], size=64) == b"from the cache"
        service.render(ENV, *states[0], size=64, view="front")
        assert len(list(tmp_path.rglob("*.jpg"))) == 2


def test_an_unwritable_cache_only_costs_speed(
    tmp_path: Path, states: list[State], caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "file").write_text("in the way")  # fails for root too, unlike a chmod
    cache = RenderCache(tmp_path / "file" / "renders")
    with RenderService() as bare:
        expected = [bare.render(ENV, *s, size=48) for s in states[:2]]
    with (
        caplog.at_level("WARNING", logger="engine.render.service"),
        RenderService(cache) as service,
    ):
        got = [service.render(ENV, *s, size=48) for s in states[:2]]
        assert service.render_many(ENV, states[:2], size=48) == expected
    assert got == expected
    warnings = [r for r in caplog.records if "not writable" in r.getMessage()]
    assert len(warnings) == 1 and "file/renders" in warnings[0].getMessage()


def test_thumbnail_and_quality_settings(service: RenderService, states: list[State]) -> None:
    spec = RenderSpec.thumbnail(view="three-quarter")
    thumb = decode(next(service.iter_render(ENV, [states[0]], spec)))
    assert thumb.size == (THUMBNAIL_SIZE, THUMBNAIL_SIZE)
    fast = service.render(ENV, *states[0], size=64, fmt="png")
    fine = service.render(ENV, *states[0], size=64, fmt="png", quality=True)
    assert decode(fine).size == (64, 64) and fine != fast


def test_other_mujoco_env(service: RenderService) -> None:
    image = decode(service.render("Hopper-v5", *rollout_states("Hopper-v5", 1)[0], size=96))
    assert robot_mask(image).mean() > 0.002


@pytest.mark.parametrize(
    "options",
    [
        {"view": "top"},
        {"size": 15},
        {"size": 100_000},
        {"size": True},
        {"size": 64.0},
        {"fmt": "gif"},
    ],
)
def test_bad_options_raise_input_error(options: dict) -> None:
    with pytest.raises(InputError):
        RenderSpec(**options)


def test_bad_state_or_env_raise_input_error(service: RenderService, states: list[State]) -> None:
    qpos, qvel = states[0]
    with pytest.raises(InputError, match="qpos"):
        service.render(ENV, qpos[:-1], qvel)
    with pytest.raises(InputError, match="unknown env"):
        service.render("NoSuchEnv-v0", qpos, qvel)
    assert decode(service.render(ENV, qpos, qvel, size=32)).size == (32, 32)  # still serving


def test_closed_service_refuses_work(states: list[State]) -> None:
    service = RenderService()
    service.render(ENV, *states[0], size=32)
    service.close()
    service.close()
    with pytest.raises(RuntimeError, match="closed"):
        service.render(ENV, *states[0], size=32)


def test_shared_service_is_one_instance_until_shutdown(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ACV_RENDER_CACHE", str(tmp_path))
    shutdown_render_service()
    with ThreadPoolExecutor(max_workers=4) as pool:
        services = set(pool.map(lambda _: get_render_service(), range(8)))
    assert len(services) == 1
    (shared,) = services
    assert shared.cache is not None and shared.cache.root == tmp_path
    shutdown_render_service()
    assert get_render_service() is not shared
    shutdown_render_service()


EXIT_WHILE_RENDERING = """
import atexit, sys, threading
import numpy as np
import engine.render.renderer as renderer
from engine.render import RenderService

failures = []
atexit.register(lambda: failures and print(*failures, file=sys.stderr))  # runs last
frame = renderer.FrameRenderer.frame
batch_started = threading.Event()

def recording_frame(self, **kwargs):  # errors on the render thread, even if nobody reads them
    if kwargs["spec"].size == 400:
        batch_started.set()
    try:
        return frame(self, **kwargs)
    except Exception as exc:
        failures.append(repr(exc))
        raise

renderer.FrameRenderer.frame = recording_frame
service = RenderService()
qpos = np.array([0.0, 1.25, 0.0, 0.0, 0.0, 0.0])
service.render("Hopper-v5", qpos, np.zeros(6), size=32)

def batch():
    try:
        service.render_many("Hopper-v5", [(qpos, np.zeros(6))] * 50, size=400)
    except RuntimeError as exc:  # submitting after the exit handler closed the service
        assert "closed" in str(exc), exc

threading.Thread(target=batch, daemon=True).start()
batch_started.wait(60)  # exit while the batch renders, not before it began
print("bye")
"""


@pytest.mark.process
def test_exit_while_rendering_is_quiet() -> None:
    done = subprocess.run(
        [sys.executable, "-c", EXIT_WHILE_RENDERING], capture_output=True, text=True, timeout=120
    )
    assert (done.returncode, done.stdout, done.stderr) == (0, "bye\n", "")
