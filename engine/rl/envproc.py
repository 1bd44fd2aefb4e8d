"""The env helper process of :class:`engine.rl.split_vecenv.SplitVectorEnv`, both ends.

The helper holds the split vector env's remote sub-envs and steps, resets, snapshots and
restores them on the learner's commands (:func:`serve`, :class:`_Server`);
:class:`HelperProcess` is the learner's end: it starts the helper, sends it commands and
reads its results.

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
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from engine.envs import make_env
from engine.rl.env_snapshot import restore_arrays, snapshot_arrays
from engine.rl.shaping import StateInfo

#: Seconds to wait for the helper's answers and exit after ``close`` before killing it.
_JOIN_S = 10.0


def make_sub_env(env_id: str) -> gym.Env[Any, Any]:
    """One training sub-env: ``env_id`` reporting the reached ``qpos``."""
    return StateInfo(make_env(env_id, disable_env_checker=True))


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


class HelperProcess:
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
