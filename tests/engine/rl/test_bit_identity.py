"""Bit-identity: the two regression tests that class every change to training and judging.

Values committed in ``data/bit_identity/`` before a change are its reference, one pair of files
per kind of CPU kernel torch picks (``<name>-<capability>.json``, :data:`CPU_CAPABILITY`):

- ``training-<capability>.json``: per algorithm, the metrics rows of a 3-update Humanoid-v5
  run with the product's hyper-parameters (4 envs x 512 steps, 10 epochs of 32 minibatches of
  64, 2x64 tanh networks, observation and reward normalisation, float32, one torch thread), and
  a SHA-256 of each part of its final checkpoint's content;
- ``judging-<capability>.json``: the ``behaviour`` and ``return`` measures of the committed
  checkpoint ``judged.pt`` (that bipars-em run's networks and normaliser) over the committed bracket
  ``advice.json``, computed as :func:`engine.validation.measure.measure` computes them
  (:func:`engine.verdict_runs.judge_scores` at the default rollouts).

Classification rule: a change is **bit-identical** when these tests pass unchanged, and
**number-altering** when the committed values must be regenerated (``regenerate.py`` in that
folder; its docstring says how, and that the commit must say so). Equality is exact: JSON
round-trips float64 exactly. That a stopped-and-resumed run equals an uninterrupted one is
``test_rl_runner.py::test_resume_after_a_stop_matches_an_uninterrupted_run``.

The values hold on one platform: torch and its BLAS pick kernels by CPU (an AVX512 machine
trains other last bits than an AVX2 one), and other versions of torch, numpy, MuJoCo or
Gymnasium may change them too. So the reference is kept per CPU capability, each made by the
commit the others were made by (today round 2's frozen training code, docs/validation.md §6,
ef285ec) on such a machine (``regenerate.py`` says how); the files record the platform they were
made on (:func:`environment`), and a failure prints it beside this one's. A machine whose
capability has no file fails, saying so: its reference has to be made from that commit, never
from the code under test.
"""

from __future__ import annotations

import copy
import hashlib
import json
import platform
import shutil
from pathlib import Path
from typing import Any

import gymnasium
import mujoco
import numpy as np
import pytest
import torch

from engine.rl.behaviour import RolloutOptions
from engine.rl.checkpoint import checkpoint_path, find_checkpoint, load_checkpoint
from engine.rl.config import ALGOS, TrainConfig
from engine.rl.judge_cache import file_digest
from engine.rl.logger import read_metrics
from engine.rl.optim import flat_adam, flat_step, flat_zero_grad
from engine.rl.runner import train
from engine.treefile import TreeDocument, load_tree
from engine.verdict_runs import judge_scores

DATA = Path(__file__).parent / "data" / "bit_identity"
#: The kernels torch dispatches to on this machine ("AVX2", "AVX512", ...).
CPU_CAPABILITY = torch.backends.cpu.get_cpu_capability()
TRAINING = DATA / f"training-{CPU_CAPABILITY}.json"
JUDGING = DATA / f"judging-{CPU_CAPABILITY}.json"
ADVICE = DATA / "advice.json"
JUDGED = DATA / "judged.pt"
UPDATES = 3
#: Metrics row fields left out of the comparison: they measure the clock, not training.
WALL_CLOCK = {
    "time": "time.time() when the update ended",
    "sps": "env steps per wall-clock second",
}
#: The judges measured (engine.validation.measure.JUDGES less the critic's reference).
JUDGES = ("behaviour", "return")


def bit_identity_config(algo: str) -> TrainConfig:
    """The product's defaults, cut to :data:`UPDATES` updates (one checkpoint, at the end)."""
    return TrainConfig(algo=algo, total_timesteps=UPDATES * TrainConfig().batch_size)


def advice_tree() -> TreeDocument:
    """The committed Humanoid-v5 bracket: every run's advice (``ppo`` only logs its F)."""
    return load_tree(ADVICE)


def environment() -> dict[str, str]:
    """What decides the last bits besides the code: versions and the CPU's kernels."""
    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "torch": torch.__version__,
        "torch_cpu_capability": CPU_CAPABILITY,
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
        "gymnasium": gymnasium.__version__,
    }


def _feed(h: Any, value: Any) -> None:
    """Add ``value`` to the hash ``h`` exactly: dtypes, shapes and bytes, not reprs."""
    if isinstance(value, dict):
        h.update(b"{%d" % len(value))
        for key, item in value.items():
            _feed(h, key)
            _feed(h, item)
    elif isinstance(value, list | tuple):
        h.update(b"[%d" % len(value))
        for item in value:
            _feed(h, item)
    elif isinstance(value, torch.Tensor):
        _feed(h, value.detach().cpu().numpy())
    elif isinstance(value, np.ndarray | np.generic):
        array = np.ascontiguousarray(value)
        h.update(f"{array.dtype.str}{array.shape}".encode())
        h.update(array.tobytes())
    elif isinstance(value, float):
        h.update(f"float:{value.hex()};".encode())
    else:  # str, int, bool, None
        text = str(value)
        h.update(f"{type(value).__name__}:{len(text)}:{text}".encode())


def state_digests(state: dict[str, Any]) -> dict[str, str]:
    """SHA-256 of each top-level part of a checkpoint (agent, optimiser, envs, ...).

    The content is hashed, not the file: a checkpoint file is byte-stable today, but a
    serialisation change would alter its bytes without altering a number.
    """
    digests = {}
    for key, value in state.items():
        h = hashlib.sha256()
        _feed(h, value)
        digests[key] = h.hexdigest()
    return digests


def training_numbers(algo: str, out: Path) -> dict[str, Any]:
    """Train the 3-update run of ``algo`` in ``out``: its metrics rows without the
    :data:`WALL_CLOCK` fields, and the digests of its final checkpoint."""
    train(bit_identity_config(algo), advice_tree(), out)
    rows = [{k: v for k, v in row.items() if k not in WALL_CLOCK} for row in read_metrics(out)]
    return {"rows": rows, "checkpoint": state_digests(load_checkpoint(find_checkpoint(out)))}


def judge_measures(checkpoint: Path, run: Path, judge: str) -> list[float]:
    """``judge``'s scores of every candidate of the bracket, in id order, for ``checkpoint``
    placed as the last one of the fresh run folder ``run`` (which takes the judges' cache)."""
    path = checkpoint_path(run, int(load_checkpoint(checkpoint)["timesteps"]))
    path.parent.mkdir(parents=True)
    shutil.copyfile(checkpoint, path)
    scores: list[float] = judge_scores([run], advice_tree(), judge, RolloutOptions())[0].tolist()
    return scores


def committed(path: Path) -> dict[str, Any]:
    """A committed file of expected values (this CPU capability's)."""
    if not path.is_file():
        pytest.fail(
            f"no bit-identity reference for {CPU_CAPABILITY} kernels ({path.name}): make it "
            "with data/bit_identity/regenerate.py from the commit the others were made by "
            "(its docstring)"
        )
    expected: dict[str, Any] = json.loads(path.read_text())
    return expected


def platforms(expected: dict[str, Any]) -> str:
    """Where the expected values were made, and where this test runs (for failures)."""
    return f"committed on {expected['environment']}; this is {environment()}"


@pytest.mark.training
@pytest.mark.parametrize("algo", ALGOS)
def test_training_is_bit_identical(algo: str, tmp_path: Path) -> None:
    expected = committed(TRAINING)
    got = training_numbers(algo, tmp_path / algo)
    assert got["rows"] == expected["runs"][algo]["rows"], platforms(expected)
    assert got["checkpoint"] == expected["runs"][algo]["checkpoint"], platforms(expected)


@pytest.mark.parametrize("judge", JUDGES)
def test_judging_is_bit_identical(judge: str, tmp_path: Path) -> None:
    expected = committed(JUDGING)
    assert file_digest(JUDGED) == expected["checkpoint_sha256"], "judged.pt is not the one measured"
    got = judge_measures(JUDGED, tmp_path / "run", judge)
    assert got == expected["measures"][judge], platforms(expected)


@pytest.mark.parametrize("name", ["training", "judging"])
def test_each_reference_is_filed_under_the_kernels_it_was_made_with(name: str) -> None:
    files = sorted(DATA.glob(f"{name}-*.json"))
    assert files  # a number-altering change keeps its machine's pair (regenerate.py)
    for path in files:
        made_on = committed(path)["environment"]["torch_cpu_capability"]
        assert path.stem == f"{name}-{made_on}"


def test_flat_step_is_adams_step_bit_for_bit() -> None:
    """:func:`flat_step` and :func:`flat_zero_grad` (the PPO minibatch loop's) against
    ``Adam.step`` and ``zero_grad``: equal parameters and state after annealed steps, and
    after a reload of the state (a resumed run)."""
    torch.manual_seed(0)
    nets = [torch.nn.Sequential(torch.nn.Linear(5, 8), torch.nn.Tanh(), torch.nn.Linear(8, 2))]
    nets.append(copy.deepcopy(nets[0]))
    opts = [flat_adam(list(net.parameters()), lr=3e-4) for net in nets]
    x = torch.randn(16, 5)
    for k in range(6):
        if k == 3:  # a resume: the state round-trips through state_dict
            opts[1].load_state_dict(copy.deepcopy(opts[1].state_dict()))
        for net, opt, fast in ((nets[0], opts[0], False), (nets[1], opts[1], True)):
            opt.param_groups[0]["lr"] = 3e-4 * (1 - k / 6)
            flat_zero_grad(opt) if fast else opt.zero_grad(set_to_none=False)
            net(x).square().sum().backward()
            flat_step(opt) if fast else opt.step()
    plain, flat = (opt.state_dict()["state"] for opt in opts)
    assert state_digests({"state": plain}) == state_digests({"state": flat})
    for p, q in zip(nets[0].parameters(), nets[1].parameters(), strict=True):
        assert torch.equal(p, q)
