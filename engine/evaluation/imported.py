"""An imported policy's stimuli (issue 41 with issue 44): the same windows, stills and clips
as a checkpoint's, from rollouts run where the judges run an imported policy.

An imported policy is an ONNX file from outside (:mod:`engine.policies`), so its evaluation
rollouts run as the judges' do: in a limited child process (:func:`run_in_child`, ``spawn``,
memory and time capped), never in the server. The child rolls it out with
:func:`~engine.evaluation.stimuli.policy_episodes`, the checkpoints' own code (the action mean
clipped to the action space, episode ``k`` reset with ``STIMULUS_SEED0 + k``, at most
``max_steps`` steps), and sends back the states as one float array (:func:`pack_episodes`),
read with ``allow_pickle=False``; the parent cuts it back into episodes with the burn-in and
``dt`` it computes itself. The windows are then chosen, cached and rendered as a checkpoint's:
keyed by :attr:`ImportedPolicy.digest` (the ONNX file's hash, with its normalisation's) and
the options, so a second render rolls nothing out.

The child imports this module to read its job: nothing here loads torch.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path

import numpy as np

from engine.envs import make_env
from engine.errors import InputError
from engine.evaluation.clips import Stimulus, Window, render_windows, step_dt
from engine.evaluation.stimuli import (
    STIMULUS_SEEDS,
    Episode,
    StimulusOptions,
    cached_windows,
    policy_episodes,
)
from engine.gym_types import mujoco_base
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.policies.sandbox import ChildLimits, run_in_child
from engine.render import RenderService

#: Columns of a packed row before its state: the episode's index and whether it ended.
HEAD = 2
#: Prefix of an imported policy's windows key (a checkpoint's is its file's bare SHA-256).
DIGEST_PREFIX = "onnx:"


@dataclass(frozen=True)
class EpisodesJob:
    """The child's work: the policy's stimulus episodes, packed (:func:`pack_episodes`)."""

    policy: ImportedPolicy
    options: StimulusOptions

    @property
    def env_id(self) -> str:
        """The env the job simulates."""
        return self.policy.env_id

    def __call__(self) -> np.ndarray:
        episodes = policy_episodes(OnnxPolicy(self.policy), self.env_id, self.options)
        return pack_episodes(episodes)


def pack_episodes(episodes: list[Episode]) -> np.ndarray:
    """Episodes as one float64 array, a row per env step: ``[k, ended, *qpos, *qvel]``."""
    rows = [
        np.hstack(
            [np.full((len(e.qpos), 1), k), np.full((len(e.qpos), 1), e.ended), e.qpos, e.qvel]
        )
        for k, e in enumerate(episodes)
    ]
    return np.vstack(rows).astype(np.float64)


def unpack_episodes(packed: np.ndarray, env_id: str, options: StimulusOptions) -> list[Episode]:
    """The episodes :func:`pack_episodes` packed, checked against the env's sizes and the
    options, with their seeds, burn-in and ``dt`` from here, not from the child.

    Raises:
        InputError: the array is not what the rollouts of ``options`` give.
    """
    nq, nv, dt = _env_sizes(env_id)
    burn_in = round(options.burn_in_s / dt)
    if packed.ndim != 2 or packed.shape[1] != HEAD + nq + nv:
        raise InputError(
            f"the policy's rollouts came back as {packed.shape}, not (T, {HEAD + nq + nv})"
        )
    index = packed[:, 0]
    episodes = []
    for k, seed in enumerate(STIMULUS_SEEDS[: options.windows]):
        rows = packed[index == k]
        if not 1 <= len(rows) <= options.max_steps:
            raise InputError(f"the policy's rollout {k} came back with {len(rows)} steps")
        qpos, qvel = rows[:, HEAD : HEAD + nq], rows[:, HEAD + nq :]
        episodes.append(Episode(seed, qpos, qvel, min(burn_in, len(rows)), bool(rows[0, 1]), dt))
    if sum(len(e.qpos) for e in episodes) != len(packed):
        raise InputError("the policy's rollouts came back with episodes that were not asked for")
    return episodes


def imported_episodes(
    policy: ImportedPolicy, options: StimulusOptions, limits: ChildLimits = ChildLimits()
) -> list[Episode]:
    """The policy's stimulus episodes, rolled out in a limited child process: the same
    seeds, steps and states as :func:`policy_episodes` gives in this process.

    Raises:
        InputError: the child failed, or ran out of memory or time.
    """
    packed = run_in_child(EpisodesJob(policy, options), limits)
    return unpack_episodes(packed, policy.env_id, options)


def imported_windows(
    policy: ImportedPolicy,
    options: StimulusOptions,
    out_dir: Path,
    limits: ChildLimits = ChildLimits(),
) -> list[Window]:
    """The policy's windows, chosen once per policy content and options and kept in
    ``out_dir/windows``, as a checkpoint's are (:func:`cached_windows`)."""
    rollouts = partial(imported_episodes, policy, options, limits)
    return cached_windows(DIGEST_PREFIX + policy.digest, policy.env_id, options, out_dir, rollouts)


def render_imported_stimuli(
    policy: ImportedPolicy,
    env_id: str,
    options: StimulusOptions,
    out_dir: Path,
    *,
    service: RenderService | None = None,
    limits: ChildLimits = ChildLimits(),
) -> list[Stimulus]:
    """An imported policy's stimuli, as
    :func:`~engine.evaluation.stimuli.render_run_stimuli` renders a checkpoint's.

    Raises:
        InputError: the policy is for another env, or its rollouts failed.
        BackendError: no off-screen OpenGL backend works.
    """
    if policy.env_id != env_id:
        raise InputError(f"the policy is for {policy.env_id}, not {env_id}")
    windows = imported_windows(policy, options, out_dir, limits)
    return render_windows(
        env_id, windows, options.spec, out_dir, clips=options.clips, service=service
    )


def render_imported_clips(
    policy: ImportedPolicy,
    env_id: str,
    options: StimulusOptions,
    out_dir: Path,
    *,
    service: RenderService | None = None,
    limits: ChildLimits = ChildLimits(),
) -> list[Stimulus]:
    """The policy's stimuli with clips, after :func:`render_imported_stimuli` made its
    stills: the windows and stills are read back, only the clips render."""
    clips = replace(options, clips=True)
    return render_imported_stimuli(policy, env_id, clips, out_dir, service=service, limits=limits)


def _env_sizes(env_id: str) -> tuple[int, int, float]:
    """``nq``, ``nv`` and the seconds per step of ``env_id``."""
    env = make_env(env_id)
    try:
        model = mujoco_base(env).model
        return int(model.nq), int(model.nv), step_dt(env)
    finally:
        env.close()
