"""The second core for a lone run: half of the training envs step in one helper process.

:class:`SplitVectorEnv` is a ``SyncVectorEnv`` whose last ``n - n // 2`` sub-envs are
proxies of envs living in one helper process. A step sends their actions to the helper first,
then steps the learner's own envs while the helper steps its envs, then takes the helper's
results: the learner and the helper simulate at the same time.

Why not Gymnasium's ``AsyncVectorEnv``: it runs one process per sub-env (two more processes
here, not one) and merges the batch in its own code. The proxies keep ``SyncVectorEnv``'s own
``step``, ``reset``, autoreset and ``_add_info`` for all ``n`` envs, so the batch (order,
dtypes, the ``info`` layout with its ``_key`` masks, ``final_obs``/``final_info``) is the one a
plain ``SyncVectorEnv`` builds. Each sub-env keeps its own generator and MuJoCo data, so which
process steps it changes speed, never numbers. Observations travel through shared memory;
rewards, flags and ``info`` (small) through
the pipe, pickled, which keeps their Python and numpy types exactly.

The helper process, both its side and the learner's handle on it, is :mod:`engine.rl.envproc`.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from engine.rl.envproc import HelperProcess, make_sub_env


class _RemoteEnv(gym.Env[np.ndarray, np.ndarray]):
    """Sub-env ``j`` of the helper, as ``SyncVectorEnv`` sees it."""

    def __init__(self, helper: HelperProcess, j: int, like: gym.Env[Any, Any]):
        self.helper, self.j = helper, j
        self.observation_space, self.action_space = like.observation_space, like.action_space
        self.metadata, self.render_mode, self.spec = like.metadata, like.render_mode, like.spec

    def step(self, action: np.ndarray) -> tuple[np.ndarray, Any, Any, Any, dict[str, Any]]:
        return self.helper.step_result(self.j)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is None and options is None and self.j in self.helper.resets:
            return self.helper.resets.pop(self.j)  # the autoreset after this step's end
        info = self.helper.call("reset", (self.j, {"seed": seed, "options": options}))
        return self.helper.obs[0, self.j].copy(), info


def _returning(env: gym.Env[Any, Any]) -> Callable[[], gym.Env[Any, Any]]:
    return lambda: env


class SplitVectorEnv(SyncVectorEnv):
    """``n_envs`` sub-envs of ``env_id``, same-step autoreset; ``n_envs // 2`` step in this
    process, the rest in one helper process, at the same time. Numbers equal a
    ``SyncVectorEnv`` of the same envs; :meth:`close` ends the helper.

    Args:
        env_id: a Gymnasium MuJoCo env id.
        n_envs: at least 2.
    """

    def __init__(self, env_id: str, n_envs: int):
        if n_envs < 2:
            raise ValueError("a split vector env needs at least 2 envs")
        self.n_local = n_envs // 2
        local = [make_sub_env(env_id) for _ in range(self.n_local)]
        space = local[0].observation_space
        self._helper = HelperProcess(env_id, n_envs - self.n_local, space)
        try:
            self._helper.call("make")
            remote = [_RemoteEnv(self._helper, j, local[0]) for j in range(n_envs - self.n_local)]
            fns = [_returning(env) for env in local + remote]
            super().__init__(fns, autoreset_mode=AutoresetMode.SAME_STEP)
        except BaseException:
            self._helper.close()
            raise

    def step(self, actions: np.ndarray) -> Any:
        """Send the helper its actions, then step all envs in ``SyncVectorEnv``'s order."""
        self._helper.resets.clear()
        self._helper.send("step", np.asarray(actions[self.n_local :]))
        self._helper.results = None
        try:
            return super().step(actions)
        except BaseException:
            if self._helper.pending:  # keep the pipe in step: the next command gets its answer
                self._helper.conn.recv()
                self._helper.pending = False
            raise

    def snapshots(self, snapshot: Callable[[gym.Env[Any, Any]], dict[str, Any]]) -> list[Any]:
        """Per sub-env snapshots, in order: ``snapshot`` here,
        :func:`engine.rl.env_snapshot.snapshot_arrays` there."""
        local = [snapshot(env) for env in self.envs[: self.n_local]]
        return local + list(self._helper.call("snapshot"))

    def restore(
        self, snaps: list[dict[str, Any]], restore: Callable[[gym.Env[Any, Any], Any], None]
    ) -> None:
        """Inverse of :meth:`snapshots`."""
        if len(snaps) != self.num_envs:
            raise ValueError(f"{len(snaps)} env snapshots for {self.num_envs} envs")
        for env, snap in zip(self.envs[: self.n_local], snaps, strict=False):
            restore(env, snap)
        remote = [
            snap | {"mujoco": {k: np.asarray(v) for k, v in snap["mujoco"].items()}}
            for snap in snaps[self.n_local :]
        ]
        self._helper.call("restore", remote)

    @property
    def helper_process(self) -> subprocess.Popen[bytes]:
        """The helper process (tests check that it ends)."""
        return self._helper.process

    def close_extras(self, **kwargs: Any) -> None:
        """Close the learner's envs and end the helper."""
        try:
            for env in self.envs[: self.n_local]:
                env.close()
        finally:
            self._helper.close()
