"""What a person sees of a trained agent: stills and clips of its own deterministic behaviour.

A run's checkpoint is rolled out deterministically (the action mean, clipped to the action
space, as every judge acts) for ``windows`` episodes, episode ``k`` reset with seed
``STIMULUS_SEED0 + k``. Each episode gives one *window* of ``clip_s`` seconds at a seeded
offset after the burn-in; its *still* is its middle frame, rendered as the candidates are
(same :class:`~engine.render.RenderSpec`, JPEG, through the render service), and its *clip*
is the window played at the env's real time (:mod:`engine.evaluation.clips`).

Reset seeds: ``STIMULUS_SEED0 = 2**31`` on, above every reset seed the product picks:
training resets env ``k`` of seed ``s`` with ``s + k`` once (then unseeded), and experiments
train seeds below ``PILOT_SEED_BASE = 10**6`` and pilots from there to below ``2 * 10**6``;
the behaviour judge resets from 0 and U from 10000 (``TRUTH_RESET_SEED0``); the return judge
and candidate sampling draw theirs below ``2**31``. Only a hand-picked ``--seed`` of at least
``2**31`` could meet one, and then in its first episode only.

Burn-in: the first ``burn_in_s`` seconds (1 s: 67 steps of Humanoid-v5) after each reset are
never the start of a window: every policy starts near the env's initial pose, so they say
little about the agent (:mod:`engine.rl.behaviour` drops them for the same reason). An
episode too short to hold a whole window after its burn-in is shown by its last ``clip_s``
seconds (shorter still if the whole episode is), burn-in included: an agent that only falls is
shown falling, not left out.

Files are content-addressed under ``out_dir`` (stills and clips by hashes of their states, the
windows by a hash of the checkpoint's bytes and the options): no file name holds a run id,
seed, arm or checkpoint name.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from engine.envs import make_env, restore
from engine.errors import InputError
from engine.evaluation.clips import (
    Policy,
    Stimulus,
    Window,
    render_windows,
    roll_forward,
    step_dt,
    window_span,
)
from engine.evaluation.window_files import dump_windows, load_windows
from engine.render import RenderService, RenderSpec
from engine.render.cache import write_atomically
from engine.render.views import DEFAULT_SIZE, DEFAULT_VIEW
from engine.rl.judge_cache import file_digest

#: Episode ``k`` of a run's stimuli resets with ``STIMULUS_SEED0 + k`` (see the module doc).
STIMULUS_SEED0 = 2**31
MAX_WINDOWS = 64
#: Every reset seed stimuli may use.
STIMULUS_SEEDS = range(STIMULUS_SEED0, STIMULUS_SEED0 + MAX_WINDOWS)
#: Part of the windows' cache key: bump it when how windows are chosen changes.
WINDOWS_VERSION = 1


@dataclass(frozen=True)
class StimulusOptions:
    """What is shown of each run.

    Attributes:
        windows: windows per run, one per episode (4: at 20 pairs over 2k = 10 runs, a
            participant sees each run 4 times, each time doing something else).
        clip_s: seconds per window (2 s: a gait cycle or two, short enough to compare).
        fps: frames per second of clips, about (the stride is a whole number of env steps).
        burn_in_s: seconds after each reset no window starts in (1 s, see the module doc).
        max_steps: env steps per episode at most (1000, the MuJoCo envs' own time limit).
        seed: seed of the windows' offsets within their episodes.
        clips: whether to render clips as well as stills.
        view: the camera (the candidates' default).
        size: pixels per side of stills and clips (the candidates' default, 480).
    """

    windows: int = 4
    clip_s: float = 2.0
    fps: float = 15.0
    burn_in_s: float = 1.0
    max_steps: int = 1000
    seed: int = 0
    clips: bool = True
    view: str = DEFAULT_VIEW
    size: int = DEFAULT_SIZE

    def __post_init__(self) -> None:
        if not 1 <= self.windows <= MAX_WINDOWS or self.max_steps < 1 or self.seed < 0:
            raise InputError(
                f"stimuli need 1..{MAX_WINDOWS} windows, max_steps >= 1 and a seed >= 0, got "
                f"{self.windows}, {self.max_steps}, {self.seed}"
            )
        if not (0 < self.clip_s <= 10 and 0 < self.fps <= 60 and 0 <= self.burn_in_s <= 10):
            raise InputError(
                "stimuli need 0 < clip_s <= 10, 0 < fps <= 60 and 0 <= burn_in_s <= 10, got "
                f"{self.clip_s}, {self.fps}, {self.burn_in_s}"
            )
        RenderSpec(view=self.view, size=self.size)  # raises InputError on a bad view or size

    @property
    def spec(self) -> RenderSpec:
        """The render settings of stills (JPEG) and clips."""
        return RenderSpec(view=self.view, size=self.size)


@dataclass(frozen=True, eq=False)
class Episode:
    """One deterministic episode of a policy from a seeded reset.

    Attributes:
        seed: its reset seed.
        qpos: positions after each env step, burn-in included, shape ``(T, nq)``.
        qvel: velocities after each env step, shape ``(T, nv)``.
        burn_in: leading steps that are burn-in (at most ``T``).
        ended: whether it terminated or was truncated (else it hit ``max_steps``).
        dt: the env's seconds per step.
    """

    seed: int
    qpos: np.ndarray
    qvel: np.ndarray
    burn_in: int
    ended: bool
    dt: float

    @property
    def kept(self) -> tuple[np.ndarray, np.ndarray]:
        """The states after the burn-in: shapes ``(T - burn_in, nq)`` and ``(.., nv)``."""
        return self.qpos[self.burn_in :], self.qvel[self.burn_in :]


def rollout_states(checkpoint: Path, env_id: str, options: StimulusOptions) -> list[Episode]:
    """The checkpoint's deterministic episodes, one per window, reset from
    :data:`STIMULUS_SEED0` on (no rendering). Loads torch here, not on import: an imported
    policy's rollouts import this module in a child that must not load it."""
    from engine.rl.trained import deterministic_policy, load_agent

    return policy_episodes(deterministic_policy(load_agent(checkpoint)), env_id, options)


def policy_episodes(policy: Policy, env_id: str, options: StimulusOptions) -> list[Episode]:
    """``options.windows`` episodes of ``policy`` (observation -> action mean), episode ``k``
    reset with ``STIMULUS_SEED0 + k``, each at most ``options.max_steps`` steps."""
    env = make_env(env_id)
    try:
        dt = step_dt(env)
        burn_in = round(options.burn_in_s / dt)
        episodes = []
        for seed in STIMULUS_SEEDS[: options.windows]:
            obs, _ = env.reset(seed=seed)
            qpos, qvel, ended = roll_forward(env, policy, obs, options.max_steps)
            episodes.append(Episode(seed, qpos, qvel, min(burn_in, len(qpos)), ended, dt))
    finally:
        env.close()
    return episodes


def window_start(steps: int, burn_in: int, span: int, u: float) -> int:
    """First step of a window of ``span`` steps in an episode of ``steps``: at fraction ``u``
    in ``[0, 1)`` of the starts after the burn-in, or the last ``span`` steps (or 0) when the
    episode is too short for one after it."""
    room = steps - burn_in - span + 1
    return burn_in + int(u * room) if room > 0 else max(0, steps - span)


def choose_windows(episodes: list[Episode], options: StimulusOptions) -> list[Window]:
    """One window per episode (:func:`rollout_states`), at offsets drawn from
    ``options.seed``, of ``options.clip_s`` seconds at about ``options.fps``."""
    dt = episodes[0].dt
    stride, span = window_span(dt, options.fps, options.clip_s)
    draws = np.random.default_rng(options.seed).random(len(episodes))
    windows = []
    for i, (episode, u) in enumerate(zip(episodes, draws, strict=True)):
        start = window_start(len(episode.qpos), episode.burn_in, span, float(u))
        frames = slice(start, start + span, stride)
        qpos, qvel = episode.qpos[frames], episode.qvel[frames]
        windows.append(Window(i, qpos, qvel, 1000 * stride * dt, len(qpos) // 2, start))
    return windows


def run_windows(
    checkpoint: Path, env_id: str, options: StimulusOptions, out_dir: Path
) -> list[Window]:
    """The run's windows, chosen once per checkpoint content and options and kept in
    ``out_dir/windows`` (so clips rendered after the stills roll nothing out again)."""
    rollouts = partial(rollout_states, checkpoint, env_id, options)
    return cached_windows(file_digest(checkpoint), env_id, options, out_dir, rollouts)


def cached_windows(
    digest: str,
    env_id: str,
    options: StimulusOptions,
    out_dir: Path,
    episodes: Callable[[], list[Episode]],
) -> list[Window]:
    """The windows of the policy whose content hash is ``digest``: read from
    ``out_dir/windows``, else chosen from ``episodes()`` and stored there."""
    path = Path(out_dir) / "windows" / f"{_windows_key(digest, env_id, options)}.npz"
    if path.is_file():
        return load_windows(path)
    windows = choose_windows(episodes(), options)
    write_atomically(path, dump_windows(windows))
    return windows


def render_run_stimuli(
    checkpoint: Path,
    env_id: str,
    options: StimulusOptions,
    out_dir: Path,
    *,
    service: RenderService | None = None,
) -> list[Stimulus]:
    """A run's stimuli: stills, and clips where ``options.clips``; what is stored is reused.

    Meant for a background thread: stills go through ``service`` (the process-wide one by
    default), clips render on the calling thread. Call it with ``clips=False`` first for a
    study that is ready with stills, then :func:`render_run_clips`.

    Raises:
        InputError: the checkpoint is not an ACV checkpoint, or the env is unknown.
        BackendError: no off-screen OpenGL backend works.
    """
    windows = run_windows(checkpoint, env_id, options, out_dir)
    return render_windows(
        env_id, windows, options.spec, out_dir, clips=options.clips, service=service
    )


def render_run_clips(
    checkpoint: Path,
    env_id: str,
    options: StimulusOptions,
    out_dir: Path,
    *,
    service: RenderService | None = None,
) -> list[Stimulus]:
    """The run's stimuli with clips, after :func:`render_run_stimuli` made its stills: the
    windows and stills are read back, only the clips render."""
    clips = replace(options, clips=True)
    return render_run_stimuli(checkpoint, env_id, clips, out_dir, service=service)


def render_candidate_clip(
    policy: Policy,
    env_id: str,
    qpos: np.ndarray,
    qvel: np.ndarray,
    options: StimulusOptions,
    out_dir: Path,
    *,
    service: RenderService | None = None,
) -> Stimulus:
    """A candidate's clip: from its state ``(qpos, qvel)``, shapes ``(nq,)`` and ``(nv,)``,
    ``clip_s`` seconds under the deterministic ``policy`` that sampled it (its pilot or
    baseline run). No randomness enters after the state is restored; the reset before it
    uses ``STIMULUS_SEED0``. Its still is the candidate's own state (frame 0)."""
    env = make_env(env_id)
    try:
        env.reset(seed=STIMULUS_SEED0)
        dt = step_dt(env)
        stride, span = window_span(dt, options.fps, options.clip_s)
        obs = restore(env, qpos, qvel)
        q, v, _ = roll_forward(env, policy, obs, span - 1)
    finally:
        env.close()
    frames = slice(0, span, stride)
    all_q, all_v = np.vstack([qpos, q])[frames], np.vstack([qvel, v])[frames]
    window = Window(0, all_q, all_v, 1000 * stride * dt, 0, 0)
    return render_windows(env_id, [window], options.spec, out_dir, clips=True, service=service)[0]


def _windows_key(digest: str, env_id: str, options: StimulusOptions) -> str:
    """What decides the windows: the policy's content hash, the env and the rollout options."""
    o = options
    text = (
        f"acv-stimulus-windows/{WINDOWS_VERSION}|{digest}|{env_id}|"
        f"{STIMULUS_SEED0}|{o.windows}|{o.clip_s!r}|{o.fps!r}|{o.burn_in_s!r}|{o.max_steps}|"
        f"{o.seed}"
    )
    return hashlib.blake2b(text.encode(), digest_size=20).hexdigest()
