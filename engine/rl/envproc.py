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

Why a plain subprocess and not ``multiprocessing``: the worker's run processes are daemonic
``multiprocessing`` children, and those may not start children of their own. So the helper is
``python -c`` with the learner's end of a socket pair (a ``multiprocessing`` ``Connection``)
and a ``memfd`` mapped by both for the observations (Gymnasium's ``create_shared_memory``
needs ``multiprocessing``'s handle passing). The helper ignores SIGINT and SIGTERM (a stop
reaches the learner, which checkpoints through the helper) and exits when the learner's end of
the socket closes, so it never outlives the learner, even one killed with SIGKILL.

This module imports no torch: the helper is spawned, and imports only what stepping needs.
"""

from __future__ import annotations

import mmap
import os
import signal
import subprocess
import sys
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium.vector import AutoresetMode, SyncVectorEnv

from engine.envs import make_env
from engine.gym_types import mujoco_base
from engine.rl.shaping import StateInfo

#: Seconds to wait for the helper's answers and exit after ``close`` before killing it.
_JOIN_S = 10.0


def make_sub_env(env_id: str) -> gym.Env[Any, Any]:
    """One training sub-env: ``env_id`` reporting the reached ``qpos``."""
    return StateInfo(make_env(env_id, disable_env_checker=True))


def _time_limit(env: gym.Env[Any, Any]) -> gym.wrappers.TimeLimit[Any, Any] | None:
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            return env
        env = env.env
    return None


def _data_arrays(data: mujoco.MjData) -> dict[str, np.ndarray]:
    return {
        name: value
        for name in dir(data)
        if not name.startswith("_") and isinstance(value := getattr(data, name), np.ndarray)
    }


def snapshot_arrays(env: gym.Env[Any, Any]) -> dict[str, Any]:
    """:func:`engine.rl.vecenv.snapshot_env` with numpy arrays (what the helper sends)."""
    base = mujoco_base(env)
    limit = _time_limit(env)
    return {
        "mujoco": {k: v.copy() for k, v in _data_arrays(base.data).items()},
        "time": float(base.data.time),
        "elapsed_steps": None if limit is None else limit._elapsed_steps,
        "np_random": base.np_random.bit_generator.state,
    }


def restore_arrays(env: gym.Env[Any, Any], snap: dict[str, Any]) -> None:
    """Inverse of :func:`snapshot_arrays`; its arrays may be numpy arrays or CPU tensors."""
    base = mujoco_base(env)
    for name, array in _data_arrays(base.data).items():
        saved = np.asarray(snap["mujoco"][name])
        # per-constraint buffers (efc_*) change size every step and are rebuilt by mj_step
        if saved.shape == array.shape:
            array[...] = saved
    base.data.time = snap["time"]
    limit = _time_limit(env)
    if limit is not None:
        limit._elapsed_steps = snap["elapsed_steps"]
    base.np_random.bit_generator.state = snap["np_random"]


class _Server:
    """The helper's side: steps, resets, snapshots and restores its ``n`` envs on request.

    A finished env is reset at once, as ``SyncVectorEnv``'s same-step autoreset does, so that
    the learner finds both results ready. ``obs[0]`` holds the steps' observations, ``obs[1]``
    the autoresets' (the shared memory).
    """

    def __init__(self, env_id: str, n: int, obs: np.ndarray):
        self.env_id, self.n, self.obs = env_id, n, obs
        self.envs: list[gym.Env[Any, Any]] = []

    def _put(self, which: int, j: int, obs: np.ndarray) -> None:
        if obs.dtype != self.obs.dtype:  # shared memory would cast: the batch would differ
            raise TypeError(f"observation dtype {obs.dtype}, space dtype {self.obs.dtype}")
        self.obs[which, j] = obs

    def make(self, _: Any) -> None:
        self.envs = [make_sub_env(self.env_id) for _ in range(self.n)]
        space = self.envs[0].observation_space
        if (space.shape, space.dtype) != (self.obs.shape[2:], self.obs.dtype):
            raise TypeError(f"the helper's observation space {space} is not the learner's")

    def step(self, actions: np.ndarray) -> list[Any]:
        out = []
        for j, (env, action) in enumerate(zip(self.envs, actions, strict=True)):
            obs, reward, terminated, truncated, info = env.step(action)
            self._put(0, j, obs)
            reset_info = None
            if terminated or truncated:
                obs, reset_info = env.reset()
                self._put(1, j, obs)
            out.append((reward, terminated, truncated, info, reset_info))
        return out

    def reset(self, arg: tuple[int, dict[str, Any]]) -> dict[str, Any]:
        j, kwargs = arg
        obs, info = self.envs[j].reset(**kwargs)
        self._put(0, j, obs)
        return info

    def snapshot(self, _: Any) -> list[dict[str, Any]]:
        return [snapshot_arrays(env) for env in self.envs]

    def restore(self, snaps: list[dict[str, Any]]) -> None:
        for env, snap in zip(self.envs, snaps, strict=True):
            restore_arrays(env, snap)

    def close(self, _: Any) -> None:
        for env in self.envs:
            env.close()


def _shared(fd: int, n: int, shape: tuple[int, ...], dtype: np.dtype[Any]) -> np.ndarray:
    """The (2, n, *shape) observation buffers in the memfd ``fd`` (mapped, not copied)."""
    size = 2 * n * int(np.prod(shape)) * dtype.itemsize
    if os.fstat(fd).st_size < size:
        os.ftruncate(fd, size)
    return np.frombuffer(mmap.mmap(fd, size), dtype=dtype).reshape(2, n, *shape)


def serve(conn_fd: int, obs_fd: int, env_id: str, n: int, shape: str, dtype: str) -> None:
    """The helper process: answer the learner's commands until ``close``, or until the
    learner's end of the socket closes (the learner died): the helper never outlives it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # stops are the learner's to handle
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    conn = Connection(conn_fd)
    obs = _shared(obs_fd, n, tuple(int(d) for d in shape.split(",") if d), np.dtype(dtype))
    server = _Server(env_id, n, obs)
    while True:
        try:
            cmd, arg = conn.recv()
        except (EOFError, OSError):
            break
        try:
            result = getattr(server, cmd)(arg)
        except Exception:  # sent to the learner, which raises it
            conn.send(("error", traceback.format_exc()))
        else:
            conn.send(("ok", result))
        if cmd == "close":
            break
    conn.close()


class _Helper:
    """The learner's side of the helper process: the socket, the shared buffers, the results."""

    def __init__(self, env_id: str, n: int, space: gym.Space[Any]):
        if space.shape is None or space.dtype is None:
            raise TypeError(f"a split vector env needs array observations, not {space}")
        self.n = n
        obs_fd = os.memfd_create("acv-env-obs")
        try:
            self.obs = _shared(obs_fd, n, space.shape, np.dtype(space.dtype))
            self.conn, child = Pipe()
            try:
                fds = (child.fileno(), obs_fd)
                args = (*fds, env_id, n, ",".join(map(str, space.shape)), np.dtype(space.dtype).str)
                code = f"from engine.rl.envproc import serve; serve(*{args!r})"
                root = str(Path(__file__).resolve().parents[2])  # where ``engine`` is imported from
                path = os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])])
                self.process = subprocess.Popen(
                    [sys.executable, "-c", code],
                    pass_fds=fds,
                    env=os.environ | {"PYTHONPATH": path},
                    stdin=subprocess.DEVNULL,
                )
            finally:
                child.close()  # so that the helper sees EOF when the learner's end closes
        finally:
            os.close(obs_fd)  # the mapping stays
        self.results: list[Any] | None = None
        self.pending = False
        self.resets: dict[int, tuple[np.ndarray, dict[str, Any]]] = {}

    def call(self, cmd: str, arg: Any = None) -> Any:
        """Send a command and wait for its result."""
        self.send(cmd, arg)
        return self.receive()

    def send(self, cmd: str, arg: Any) -> None:
        self.conn.send((cmd, arg))
        self.pending = True

    def receive(self) -> Any:
        try:
            status, result = self.conn.recv()
        except EOFError as exc:
            code = self.process.poll()
            raise RuntimeError(f"the env helper process exited (status {code})") from exc
        finally:
            self.pending = False
        if status == "error":
            raise RuntimeError(f"the env helper process failed:\n{result}")
        return result

    def step_result(self, j: int) -> tuple[np.ndarray, Any, Any, Any, dict[str, Any]]:
        """Env ``j``'s result of the step sent last (received once for all envs)."""
        if self.results is None:
            self.results = self.receive()
        reward, terminated, truncated, info, reset_info = self.results[j]
        if reset_info is not None:
            self.resets[j] = (self.obs[1, j].copy(), reset_info)
        if j == self.n - 1:
            self.results = None
        return self.obs[0, j].copy(), reward, terminated, truncated, info

    def close(self) -> None:
        """End the helper: politely, then by force; never leaves it running."""
        try:
            if self.process.poll() is None:
                if self.pending and self.conn.poll(_JOIN_S):  # an interrupted step's answer
                    self.conn.recv()
                self.conn.send(("close", None))
                if self.conn.poll(_JOIN_S):
                    self.conn.recv()
        except (EOFError, OSError):
            pass
        finally:
            self.conn.close()  # EOF: a helper that did not read "close" exits too
            try:
                self.process.wait(_JOIN_S)
            except subprocess.TimeoutExpired:
                self.process.kill()  # it ignores SIGTERM
                self.process.wait()


class _RemoteEnv(gym.Env[np.ndarray, np.ndarray]):
    """Sub-env ``j`` of the helper, as ``SyncVectorEnv`` sees it."""

    def __init__(self, helper: _Helper, j: int, like: gym.Env[Any, Any]):
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
        self._helper = _Helper(env_id, n_envs - self.n_local, space)
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
        """Per sub-env snapshots, in order: ``snapshot`` here, :func:`snapshot_arrays` there."""
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
