"""The training vector env, and exact snapshots of its sub-envs for resumable checkpoints."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import torch

from engine.rl.env_snapshot import restore_arrays, snapshot_arrays
from engine.rl.envproc import make_sub_env
from engine.rl.shaping import AdviceFn, AdviceShaping
from engine.rl.split_vecenv import SplitVectorEnv

if TYPE_CHECKING:
    from gymnasium.vector import SyncVectorEnv


def make_vec_env(
    env_id: str,
    n_envs: int,
    advice: AdviceFn | None,
    advice_scale: float = 1.0,
    advice_offset: float = 0.0,
    processes: int = 1,
) -> AdviceShaping:
    """``n_envs`` copies of ``env_id`` in a ``SyncVectorEnv`` with same-step autoreset.

    On two cores the synchronous env beats ``AsyncVectorEnv``: the learner and the simulator
    alternate, so worker processes only add pickling and IPC. With ``processes=2`` (a lone
    run, the second core idle) half of the envs step in one helper process while the learner
    steps the other half (:class:`engine.rl.split_vecenv.SplitVectorEnv`): the same numbers, faster.

    Raises:
        InputError: ``env_id`` is not a Gymnasium MuJoCo env.
        ValueError: ``processes`` is not 1 or 2.
    """
    if processes not in (1, 2):
        raise ValueError(f"env processes must be 1 or 2, not {processes}")
    vec: gym.vector.SyncVectorEnv[Any, Any]
    if processes == 2 and n_envs >= 2:
        vec = SplitVectorEnv(env_id, n_envs)
    else:
        vec = gym.vector.SyncVectorEnv(
            [lambda: make_sub_env(env_id)] * n_envs,
            autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
        )
    return AdviceShaping(vec, advice, advice_scale, advice_offset)


def snapshot_env(env: gym.Env[Any, Any]) -> dict[str, Any]:
    """Everything that decides a sub-env's future: MuJoCo data, step count, rng state.

    We copy every array of ``MjData``, not only the integration state: Gymnasium envs read
    quantities left over from the previous ``mj_step`` (Humanoid's centre of mass uses the
    pre-integration ``xipos``), and recomputing them with ``mj_forward`` would change rewards.
    """
    return _as_tensors(snapshot_arrays(env))


def _as_tensors(snap: dict[str, Any]) -> dict[str, Any]:
    """A :func:`engine.rl.env_snapshot.snapshot_arrays` snapshot with its arrays as tensors."""
    return snap | {"mujoco": {k: torch.from_numpy(v) for k, v in snap["mujoco"].items()}}


def restore_env(env: gym.Env[Any, Any], snap: dict[str, Any]) -> None:
    """Inverse of :func:`snapshot_env` (``env`` must have been reset once)."""
    restore_arrays(env, snap)


def snapshot_vec(envs: AdviceShaping) -> list[dict[str, Any]]:
    """Snapshots of all sub-envs of a :func:`make_vec_env` env."""
    vec = envs.unwrapped
    if isinstance(vec, SplitVectorEnv):
        return [_as_tensors(snap) for snap in vec.snapshots(snapshot_arrays)]
    return [snapshot_env(env) for env in _sub_envs(envs)]


def restore_vec(envs: AdviceShaping, snaps: list[dict[str, Any]]) -> None:
    """Restore the sub-envs saved by :func:`snapshot_vec`."""
    vec = envs.unwrapped
    if isinstance(vec, SplitVectorEnv):
        vec.restore(snaps, restore_env)
        return
    for env, snap in zip(_sub_envs(envs), snaps, strict=True):
        restore_env(env, snap)


def _sub_envs(envs: AdviceShaping) -> list[gym.Env[Any, Any]]:
    """The sub-envs of a :func:`make_vec_env` env (its unwrapped env is a ``SyncVectorEnv``)."""
    return cast("SyncVectorEnv[Any, Any]", envs.unwrapped).envs
