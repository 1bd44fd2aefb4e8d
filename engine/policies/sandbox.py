"""An imported policy's rollouts in a child process with memory and time limits.

The gate (:mod:`engine.policies.onnx_check`) bounds a model's file, not the work of running
it: a few allowed nodes can grow a tensor geometrically, and a judge rolls the policy out for
thousands of steps. So the judges' simulations of an imported policy run in a fresh process
(``spawn``: nothing of the server or worker is inherited) whose address space is capped with
``RLIMIT_AS`` at what the interpreter and its libraries already map (MuJoCo's included,
loaded by making the env once) plus :attr:`ChildLimits.memory_bytes` (a fixed cap would
depend on how much numpy, MuJoCo and onnxruntime map on each machine), and whose CPU time is
capped with ``RLIMIT_CPU`` as a backstop should the parent die. The parent waits at most
:attr:`ChildLimits.seconds` (the child's start included), then kills it. A child killed or
failing becomes an :class:`~engine.errors.InputError` that says why.

The result comes back as ``.npy`` bytes through a pipe and is read with
``allow_pickle=False``: even a child that misbehaved cannot make the parent unpickle.
"""

from __future__ import annotations

import contextlib
import io
import math
import multiprocessing
import resource
import signal
import threading
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any, Protocol

import numpy as np

from engine.envs import make_env
from engine.errors import InputError
from engine.policies.onnx_policy import ImportedPolicy, OnnxPolicy
from engine.rl.behaviour import RolloutOptions, visited_states
from engine.rl.returns import ReturnOptions, state_returns

MiB = 1024 * 1024
_OK, _ERROR = b"A", b"E"


@dataclass(frozen=True)
class ChildLimits:
    """What one judging child may use.

    Attributes:
        memory_bytes: address space on top of the interpreter's own once it has started.
        seconds: wall-clock time, the child's start (a second or two of imports) included.
        result_bytes: the result sent back (the visited states of 5000 Humanoid steps take
            under 1 MiB).
    """

    memory_bytes: int = 2048 * MiB
    seconds: float = 600.0
    result_bytes: int = 64 * MiB


class Job(Protocol):
    """What a child computes: a float array from rollouts in one env."""

    @property
    def env_id(self) -> str: ...

    def __call__(self) -> np.ndarray: ...


@dataclass(frozen=True)
class VisitJob:
    """The ``behaviour`` judge's rollouts: the visited ``qpos``, shape ``(T, nq)``."""

    policy: ImportedPolicy
    rollouts: RolloutOptions

    @property
    def env_id(self) -> str:
        """The env the job simulates."""
        return self.policy.env_id

    def __call__(self) -> np.ndarray:
        return visited_states(OnnxPolicy(self.policy), self.policy.env_id, self.rollouts)


@dataclass(frozen=True)
class ReturnJob:
    """The ``return`` judge's rollouts from given states: shape ``(B, rollouts)``."""

    policy: ImportedPolicy
    qpos: np.ndarray
    qvel: np.ndarray
    returns: ReturnOptions

    @property
    def env_id(self) -> str:
        """The env the job simulates."""
        return self.policy.env_id

    def __call__(self) -> np.ndarray:
        policy = OnnxPolicy(self.policy)
        return state_returns(policy, self.policy.env_id, self.qpos, self.qvel, self.returns)


def run_in_child(job: Job, limits: ChildLimits = ChildLimits()) -> np.ndarray:
    """``job()`` computed in a limited child process (see the module docstring).

    Args:
        job: a picklable job (an instance of a module-level class).
        limits: memory, time and result size.

    Raises:
        InputError: the child ran out of time or memory, failed, or sent too much.
    """
    context = multiprocessing.get_context("spawn")
    job_reader, job_writer = context.Pipe(duplex=False)
    receiver, sender = context.Pipe(duplex=False)
    child = context.Process(target=_child_main, args=(job_reader, sender, limits), daemon=True)
    child.start()
    # The child holds the only other ends: its death reads as a closed pipe on both.
    job_reader.close()
    sender.close()
    sending = threading.Thread(target=_send_job, args=(job_writer, job), daemon=True)
    sending.start()
    try:
        message = _receive(receiver, limits)
    except InputError:  # out of time, or too much sent: no reason to wait for it
        child.kill()
        raise
    finally:
        _stop(child)
        sending.join()  # the child is gone: a send still under way has failed
        job_writer.close()
        receiver.close()
    return _result(message, child.exitcode, limits)


def _send_job(writer: Connection, job: Job) -> None:
    """Send the job over a pipe of its own, from a thread, so that the time limit covers it.

    ``spawn`` writes its process object to the child before the child runs, blocking until
    the child has read it all; a child that hung or died while starting would leave a model
    larger than the pipe's buffer (64 KiB on Linux) blocked there, out of the limit's reach.
    """
    with contextlib.suppress(OSError):  # a broken pipe: the child died, its exit code says how
        writer.send(job)


def _receive(receiver: Connection, limits: ChildLimits) -> bytes | None:
    """The child's message; None when it died without one."""
    if not receiver.poll(limits.seconds):
        raise InputError(
            f"judging the policy took longer than its limit of {limits.seconds:g} s: "
            "the child process was killed"
        )
    try:
        return receiver.recv_bytes(limits.result_bytes)
    except EOFError:
        return None
    except OSError as exc:  # the message is longer than result_bytes
        raise InputError(
            f"judging the policy sent back more than {limits.result_bytes} bytes"
        ) from exc


def _stop(child: Any) -> None:
    """Wait for the child to end (it exits once it has sent), killing it after 5 s."""
    child.join(timeout=5)
    if child.is_alive():
        child.kill()
        child.join()


def _result(message: bytes | None, exitcode: int | None, limits: ChildLimits) -> np.ndarray:
    if message is None:
        raise InputError(f"judging the policy failed: the child process {_death(exitcode, limits)}")
    if message.startswith(_ERROR):
        raise InputError(message[1:].decode(errors="replace"))
    try:
        result: np.ndarray = np.load(io.BytesIO(message[1:]), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise InputError("judging the policy sent back something that is not an array") from exc
    return result


def _death(exitcode: int | None, limits: ChildLimits) -> str:
    """How the child ended, in words, with the limit it most likely hit."""
    mib = limits.memory_bytes // MiB
    if exitcode is not None and exitcode < 0:
        name = signal.Signals(-exitcode).name if -exitcode in signal.valid_signals() else "?"
        if -exitcode == signal.SIGXCPU:
            return f"ran past its CPU time limit ({name})"
        return f"was killed by {name} (over its memory limit of {mib} MiB?)"
    return f"exited with code {exitcode} (over its memory limit of {mib} MiB?)"


def _child_main(job_reader: Connection, sender: Connection, limits: ChildLimits) -> None:
    """In the child: read the job (from the parent), warm up, limit, compute; send ``A`` +
    ``.npy`` bytes or ``E`` + a message."""
    try:
        job: Job = job_reader.recv()
        job_reader.close()
        make_env(job.env_id).close()  # MuJoCo's libraries, mapped before the limit: see below
        _limit_resources(limits)
        buffer = io.BytesIO()
        np.save(buffer, np.asarray(job(), dtype=np.float64), allow_pickle=False)
        sender.send_bytes(_OK + buffer.getvalue())
    except Exception as exc:  # the policy's own failure, reported, never raised in the parent
        sender.send_bytes(_ERROR + _failure(exc, limits).encode())
    finally:
        sender.close()


def _failure(exc: Exception, limits: ChildLimits) -> str:
    """What went wrong in the child, in words; an allocation that failed (Python's
    MemoryError, onnxruntime's or MuJoCo's messages) is named as the memory limit."""
    text = str(exc).strip()
    first = text.splitlines()[0] if text else type(exc).__name__
    if isinstance(exc, MemoryError) or "alloc" in text.lower():
        mib = limits.memory_bytes // MiB
        return f"judging the policy ran out of its memory limit ({mib} MiB): {first}"
    if isinstance(exc, InputError):
        return text
    return f"judging the policy failed: {type(exc).__name__}: {first}"


def _limit_resources(limits: ChildLimits) -> None:
    """Cap the address space and the CPU seconds. The address space already mapped (the
    interpreter, numpy, onnxruntime, and MuJoCo's libraries, loaded by making the env once:
    trusted code, none of the policy's) is left out of the budget, so that the limit measures
    the policy's work, the same on every machine."""
    _lower(resource.RLIMIT_AS, _address_space() + limits.memory_bytes)
    _lower(resource.RLIMIT_CPU, math.ceil(limits.seconds) + 1)


def _lower(which: int, value: int) -> None:
    """Set both limits of ``which`` to ``value``, never above the hard limit already set."""
    _, hard = resource.getrlimit(which)
    if hard != resource.RLIM_INFINITY:
        value = min(value, hard)
    resource.setrlimit(which, (value, value))


def _address_space() -> int:
    """The process's virtual memory size in bytes (``VmSize``; 0 where /proc has none)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0
