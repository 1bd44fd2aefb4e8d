"""The second core for a lone run (issue 42 §3-4): envs stepping in one process or two.

The number of processes changes speed, never numbers: a run whose envs step half in a helper
process (``env_processes=2``) writes the committed bit-identity rows and checkpoint of the
one-process run, also when it is stopped and resumed; and the helper never outlives the run.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from engine.rl.checkpoint import find_checkpoint, load_checkpoint
from engine.rl.logger import read_metrics
from engine.rl.runner import train
from engine.rl.trainer import Trainer
from engine.rl.vecenv import make_vec_env
from tests.engine.rl.test_bit_identity import (
    TRAINING,
    WALL_CLOCK,
    advice_tree,
    bit_identity_config,
    committed,
    platforms,
    state_digests,
)

pytestmark = pytest.mark.training


def _numbers(out: Path) -> dict:
    rows = [{k: v for k, v in row.items() if k not in WALL_CLOCK} for row in read_metrics(out)]
    return {"rows": rows, "checkpoint": state_digests(load_checkpoint(find_checkpoint(out)))}


@pytest.mark.parametrize("algo", ["ppo", "bipars-em"])
def test_two_processes_give_the_one_process_run(algo: str, tmp_path: Path) -> None:
    expected = committed(TRAINING)
    train(bit_identity_config(algo), advice_tree(), tmp_path / algo, env_processes=2)
    got = _numbers(tmp_path / algo)
    assert got["rows"] == expected["runs"][algo]["rows"], platforms(expected)
    assert got["checkpoint"] == expected["runs"][algo]["checkpoint"], platforms(expected)
    assert not _helpers()  # the helper is gone with the run


def test_a_two_process_run_stopped_and_resumed_equals_the_uninterrupted_one(
    tmp_path: Path,
) -> None:
    algo, out = "bipars-em", tmp_path / "cut"
    cfg, tree = bit_identity_config(algo), advice_tree()
    calls = iter(range(10))
    stopped = train(cfg, tree, out, should_stop=lambda: next(calls) == 0, env_processes=2)
    assert stopped.name == f"step_{cfg.batch_size}.pt"
    train(cfg, None, out, resume=True, env_processes=2)
    expected = committed(TRAINING)
    got = _numbers(out)
    assert got["rows"] == expected["runs"][algo]["rows"], platforms(expected)
    assert got["checkpoint"] == expected["runs"][algo]["checkpoint"], platforms(expected)


def test_the_split_env_steps_like_the_sync_env() -> None:
    """Random actions over episode ends (same-step autoreset, ``final_obs``/``final_info``)."""
    envs = [make_vec_env("Hopper-v5", 3, None, processes=p) for p in (1, 2)]
    try:
        first = [e.reset(seed=5) for e in envs]
        _assert_same(first[0], first[1])
        rng = np.random.default_rng(0)
        ends = 0
        for _ in range(150):
            actions = rng.uniform(-1, 1, (3, 3)).astype(np.float32)
            out = [e.step(actions) for e in envs]
            _assert_same(out[0], out[1])
            ends += int(out[0][2].sum() + out[0][3].sum())
        assert ends > 0  # the autoreset path was taken
    finally:
        for e in envs:
            e.close()


def _assert_same(a: Any, b: Any) -> None:
    """Equal values, types and dtypes, recursively (info dicts in the same key order)."""
    assert type(a) is type(b)
    if isinstance(a, dict):
        assert list(a) == list(b)
        for key in a:
            _assert_same(a[key], b[key])
    elif isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _assert_same(x, y)
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape
        if a.dtype == object:
            for x, y in zip(a, b, strict=True):
                _assert_same(x, y)
        else:
            assert np.array_equal(a, b)
    else:
        assert a == b


def test_no_helper_survives_an_exception(tmp_path: Path) -> None:
    def fail(row: dict) -> None:
        raise RuntimeError("boom")

    cfg = bit_identity_config("ppo")
    with pytest.raises(RuntimeError, match="boom"):
        train(cfg, advice_tree(), tmp_path / "run", progress=fail, env_processes=2)
    assert not _helpers()
    trainer = Trainer(cfg, None, env_processes=2)
    helper = trainer.envs.unwrapped.helper_process  # type: ignore[attr-defined]
    assert _helpers() == [helper.pid]
    trainer.close()
    assert helper.poll() is not None and not _helpers()


def _helpers() -> list[int]:
    """The pids of this process's env helpers still running."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(") ", 1)[1].split()
            cmdline = (stat.parent / "cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == os.getpid() and fields[0] != "Z" and b"engine.rl.envproc" in cmdline:
            found.append(int(stat.parent.name))
    return found


def _step_in_a_daemon(queue: Any) -> None:
    envs = make_vec_env("Hopper-v5", 2, None, processes=2)
    envs.reset(seed=0)
    obs = envs.step(np.zeros((2, 3), dtype=np.float32))[0]
    envs.close()
    queue.put(obs.shape)


def test_a_daemonic_run_process_can_split_its_envs() -> None:
    """The worker's run processes are daemonic ``multiprocessing`` children, which may not
    start ``multiprocessing`` children: the helper is a plain subprocess."""
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    proc = ctx.Process(target=_step_in_a_daemon, args=(queue,), daemon=True)
    proc.start()
    assert queue.get(timeout=60) == (2, 11)
    proc.join(30)
    assert proc.exitcode == 0


_KILLED = """
import os, sys
from engine.rl.vecenv import make_vec_env
envs = make_vec_env("Hopper-v5", 2, None, processes=2)
print(envs.unwrapped.helper_process.pid, flush=True)
sys.stdin.readline()
"""


def test_no_helper_survives_a_killed_learner() -> None:
    learner = subprocess.Popen(
        [sys.executable, "-c", _KILLED],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        cwd=Path(__file__).parents[3],
    )
    assert learner.stdout is not None
    helper = int(learner.stdout.readline())
    learner.send_signal(signal.SIGKILL)
    learner.wait()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and _alive(helper):
        time.sleep(0.1)
    assert not _alive(helper)


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, reaped by init, counts as gone)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")
    return stat.exists() and stat.read_text().split(") ")[-1][:1] != "Z"
