"""Stimuli of an agent evaluation: deterministic rollouts of a checkpoint, windows after the
burn-in, stills as the candidates', clips as animated WebP at real time, cached and blind."""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from PIL.WebPImagePlugin import WebPImageFile

from engine.envs import make_env
from engine.errors import InputError
from engine.evaluation.clips import (
    frame_durations,
    frame_stride,
    step_dt,
    window_span,
)
from engine.evaluation.stimuli import (
    STIMULUS_SEED0,
    STIMULUS_SEEDS,
    StimulusOptions,
    choose_windows,
    render_candidate_clip,
    render_run_clips,
    render_run_stimuli,
    rollout_states,
    window_start,
)
from engine.render import RenderService, cache_key
from engine.render.renderer import FrameRenderer
from engine.rl import behaviour, returns
from engine.rl.checkpoint import save_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.judge_cache import file_digest
from engine.rl.trained import deterministic_policy, load_agent
from engine.rl.trainer import Trainer
from engine.validation import design, round2

ENV = "Hopper-v5"  # dt 0.008 s: at 15 fps a frame every 8 steps, 64 ms
#: Small and short: 2 windows of 6 frames (41 steps) after a 25-step burn-in, 64 px.
OPTIONS = StimulusOptions(windows=2, clip_s=0.4, burn_in_s=0.2, size=64, clips=False)
#: A run folder whose name says everything a participant must not learn.
RUN_NAME = "run-advised-arm-seed"
NAME = re.compile(r"^(windows|[0-9a-f]{2})(/[0-9a-f]{40}\.(jpg|webp|npz))?$")


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real checkpoint of an untrained ``ppo`` agent on Hopper-v5, saved as training does."""
    cfg = TrainConfig(
        algo="ppo", env_id=ENV, total_timesteps=64, n_envs=1, num_steps=64, num_minibatches=1
    )
    trainer = Trainer(cfg, None)
    try:
        return save_checkpoint(trainer.state_dict(), tmp_path_factory.mktemp(RUN_NAME), 0)
    finally:
        trainer.envs.close()


@pytest.fixture(scope="module")
def service() -> Iterator[RenderService]:
    with RenderService() as svc:  # no cache of its own: only the stimuli folder stores
        yield svc


def test_rollouts_are_deterministic(checkpoint: Path) -> None:
    first, second = (rollout_states(checkpoint, ENV, OPTIONS) for _ in range(2))
    assert [e.seed for e in first] == [STIMULUS_SEED0, STIMULUS_SEED0 + 1]
    for a, b in zip(first, second, strict=True):
        assert len(a.qpos) > 1
        np.testing.assert_array_equal(a.qpos, b.qpos)
        np.testing.assert_array_equal(a.qvel, b.qvel)
    assert not np.array_equal(first[0].qpos[:5], first[1].qpos[:5])  # reset seeds differ


def test_reset_seeds_are_disjoint_from_every_other_use() -> None:
    judges = set(range(behaviour.RolloutOptions().episodes)) | {returns.ReturnOptions().seed}
    truth = set(range(design.TRUTH_RESET_SEED0, design.TRUTH_RESET_SEED0 + 5))
    assert round2.TRUTH_RESET_SEED0 == design.TRUTH_RESET_SEED0
    assert not set(STIMULUS_SEEDS) & (judges | truth)
    # Experiments train seeds below 10**6, pilots below 2 * 10**6; sampling draws below 2**31.
    assert min(STIMULUS_SEEDS) >= 2**31


def test_windows_start_after_the_burn_in(checkpoint: Path) -> None:
    episodes = rollout_states(checkpoint, ENV, OPTIONS)
    stride, span = window_span(0.008, OPTIONS.fps, OPTIONS.clip_s)
    assert (stride, span) == (8, 41)
    for episode, window in zip(episodes, choose_windows(episodes, OPTIONS), strict=True):
        assert episode.burn_in == 25 and len(episode.qpos) >= episode.burn_in + span
        kept, _ = episode.kept
        np.testing.assert_array_equal(kept[0], episode.qpos[25])
        assert episode.burn_in <= window.start <= len(episode.qpos) - span
        frames = episode.qpos[window.start : window.start + span : stride]
        np.testing.assert_array_equal(window.qpos, frames)
        assert window.still_frame == len(frames) // 2 == 3


def test_windows_are_chosen_by_their_seed(checkpoint: Path) -> None:
    episodes = rollout_states(checkpoint, ENV, OPTIONS)
    starts = {
        seed: [w.start for w in choose_windows(episodes, replace(OPTIONS, seed=seed))]
        for seed in range(6)
    }
    assert starts[0] == [w.start for w in choose_windows(episodes, OPTIONS)]
    assert len({tuple(s) for s in starts.values()}) > 1


@pytest.mark.parametrize(
    ("steps", "burn_in", "span", "u", "start"),
    [
        (100, 25, 41, 0.0, 25),  # room after the burn-in: from its end ...
        (100, 25, 41, 0.999, 59),  # ... to the last whole window
        (50, 25, 41, 0.5, 9),  # too short after the burn-in: the last 41 steps
        (30, 25, 41, 0.5, 0),  # shorter than a window: all of it
    ],
)
def test_window_start(steps: int, burn_in: int, span: int, u: float, start: int) -> None:
    assert window_start(steps, burn_in, span, u) == start


def test_frames_play_at_the_envs_real_time() -> None:
    env = make_env("Humanoid-v5")
    try:
        dt = step_dt(env)
    finally:
        env.close()
    assert dt == pytest.approx(0.015)
    assert frame_stride(dt, 15.0) == 4 and window_span(dt, 15.0, 2.0) == (4, 129)
    assert frame_durations(3, 60.0) == [60, 60, 60]
    durations = frame_durations(4, 12.5)  # whole milliseconds, and no drift
    assert set(durations) == {12, 13} and sum(durations) == 50


def _counting_frames(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the frames the product's renderer draws from now on (any thread)."""
    calls: list[int] = []
    original: Callable[..., np.ndarray] = FrameRenderer.frame

    def counted(self: FrameRenderer, *args: Any, **kwargs: Any) -> np.ndarray:
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(FrameRenderer, "frame", counted)
    return calls


def test_stills_then_clips_cached_and_blind(
    checkpoint: Path, service: RenderService, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    stills = render_run_stimuli(checkpoint, ENV, OPTIONS, tmp_path, service=service)
    assert [s.window for s in stills] == [0, 1] and all(s.clip is None for s in stills)
    for s in stills:
        image = Image.open(tmp_path / s.still)
        assert image.format == "JPEG" and image.size == (64, 64)
        assert s.still_bytes == (tmp_path / s.still).stat().st_size
    stimuli = render_run_clips(checkpoint, ENV, OPTIONS, tmp_path, service=service)
    assert [s.still for s in stimuli] == [s.still for s in stills]
    for s in stimuli:
        assert s.clip is not None and s.n_frames == 6 and s.frame_duration_ms == 64.0
        clip = _webp(tmp_path / s.clip)
        assert clip.is_animated and clip.n_frames > 1
        assert clip.info["loop"] == 0 and _plays_in_real_time(clip, 6, 64)

    drawn = _counting_frames(monkeypatch)
    before = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
    again = render_run_clips(checkpoint, ENV, OPTIONS, tmp_path, service=service)
    assert again == stimuli and drawn == []
    assert {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()} == before

    names = [p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")]
    assert names and all(NAME.match(n) for n in names), names
    digest = file_digest(checkpoint)
    assert not any(digest[:8] in n or str(STIMULUS_SEED0) in n for n in names)


def _webp(path: Path) -> WebPImageFile:
    image = Image.open(path)
    assert isinstance(image, WebPImageFile)
    return image


def _plays_in_real_time(clip: WebPImageFile, n_frames: int, frame_ms: int) -> bool:
    """Whether the clip lasts ``n_frames`` frames of ``frame_ms``: libwebp merges a frame
    identical to the one before it into that one, adding up their durations."""
    durations = []
    for i in range(clip.n_frames):
        clip.seek(i)
        clip.load()
        durations.append(int(clip.info["duration"]))
    return sum(durations) == n_frames * frame_ms and all(d % frame_ms == 0 for d in durations)


def test_a_candidate_clip_starts_at_its_state(
    checkpoint: Path, service: RenderService, tmp_path: Path
) -> None:
    episode = rollout_states(checkpoint, ENV, OPTIONS)[0]
    qpos, qvel = episode.qpos[30], episode.qvel[30]
    policy = deterministic_policy(load_agent(checkpoint))
    stimulus = render_candidate_clip(policy, ENV, qpos, qvel, OPTIONS, tmp_path, service=service)
    key = cache_key(ENV, qpos, qvel, OPTIONS.spec)
    assert stimulus.still == f"{key[:2]}/{key}.jpg"  # the candidate's own picture
    assert stimulus.clip is not None and stimulus.n_frames == 6
    assert _plays_in_real_time(_webp(tmp_path / stimulus.clip), 6, 64)
    again = render_candidate_clip(policy, ENV, qpos, qvel, OPTIONS, tmp_path, service=service)
    assert again == stimulus  # deterministic: the same states, the same files


@pytest.mark.parametrize(
    "kwargs",
    [{"windows": 0}, {"clip_s": 0.0}, {"fps": 0.0}, {"burn_in_s": -1.0}, {"view": "top"}],
)
def test_options_are_validated(kwargs: dict[str, Any]) -> None:
    with pytest.raises(InputError):
        StimulusOptions(**kwargs)
