"""A training run as a library call: ``train(config, advice, out_dir, ...)``.

The run directory holds ``config.json``, ``metrics.jsonl`` (one row per update), TensorBoard
event files, ``advice.json`` (the advice tree, when the run has one) and
``checkpoints/step_<timesteps>.pt``. The web app's worker calls :func:`train` directly:
``progress`` receives each metrics row, ``should_stop`` cancels cleanly (a checkpoint is
written first).

Resuming continues from the latest checkpoint with the exact state of the killed run (networks,
optimisers, normalisers, random generators, and every sub-env's MuJoCo data, step count and
generator), so a resumed run writes the same metrics rows as an uninterrupted one at the same
seed; only the wall-clock fields ``sps`` and ``time`` differ. Rows the killed run wrote after
its last checkpoint are dropped, and TensorBoard purges its events after that step.
:func:`train` sets torch to one thread for the process: the networks are tiny, and more
threads only add synchronisation.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from engine.advice import AdviceReward
from engine.errors import InputError
from engine.rl.checkpoint import find_checkpoint, list_checkpoints, load_checkpoint, save_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.logger import METRICS_FILE, RunLogger
from engine.rl.shaping import AdviceFn
from engine.rl.trainer import Trainer
from engine.treefile import TreeDocument, dump_tree, load_tree

CONFIG_FILE = "config.json"
ADVICE_FILE = "advice.json"

Progress = Callable[[dict[str, Any]], None]


def train(config: TrainConfig, advice: TreeDocument | AdviceFn | None, out_dir: Path,
          progress: Progress | None = None, should_stop: Callable[[], bool] | None = None,
          resume: bool = False) -> Path:
    """Train (or continue training) and return the path of the last checkpoint written.

    Args:
        config: the run's configuration.
        advice: a Human Preference Tree (F is built from it with the config's advice options
            and saved as ``advice.json``), any F callable on ``qpos`` batches, or None (only
            for ``ppo``; on resume, ``advice.json`` is reloaded when present).
        out_dir: the run directory (created).
        progress: called with every metrics row (``sps`` included).
        should_stop: polled after every update; True writes a checkpoint and returns.
        resume: continue from the latest checkpoint in ``out_dir``; the config must match.

    Raises:
        InputError: missing or mismatched advice, an existing run without ``resume``, a
            resume without checkpoints or with another config, a corrupt checkpoint.
    """
    torch.set_num_threads(1)
    out_dir = Path(out_dir)
    if advice is None and resume:
        advice = load_run_advice(out_dir)
    advice_fn = _advice_fn(config, advice)
    state = _resume_state(config, out_dir) if resume else _check_new_dir(out_dir)
    trainer, logger = _start(config, advice, advice_fn, out_dir, state)
    try:
        return _loop(trainer, out_dir, logger, progress, should_stop)
    finally:
        logger.close()
        trainer.close()


def _start(config: TrainConfig, advice: TreeDocument | AdviceFn | None,
           advice_fn: AdviceFn | None, out_dir: Path,
           state: dict[str, Any] | None) -> tuple[Trainer, RunLogger]:
    """The trainer (restored from ``state`` on resume) and the logger of the run.

    The trainer (envs, networks: what bad input makes fail) is built before anything is
    written, and a new run's files are removed again if its start fails, so that a failed start
    never leaves a directory that refuses the next attempt as "already holds a run".
    """
    trainer = Trainer(config, advice_fn)
    existed = out_dir.exists()
    try:
        if state is not None:
            trainer.load_state_dict(state)
        else:
            _write_new_run(config, advice, out_dir)
        return trainer, RunLogger(out_dir, start=trainer.timesteps)
    except BaseException:
        trainer.close()
        if state is None:
            _undo_new_run(out_dir, existed)
        raise


def _loop(trainer: Trainer, out_dir: Path, logger: RunLogger, progress: Progress | None,
          should_stop: Callable[[], bool] | None) -> Path:
    """Iterate until done or stopped, checkpointing every ``checkpoint_every`` steps."""
    cfg = trainer.cfg
    start_steps, start_time = trainer.timesteps, time.perf_counter()
    last_saved = None
    while not trainer.done:
        row = trainer.iterate()
        row["sps"] = (trainer.timesteps - start_steps) / (time.perf_counter() - start_time)
        logger.write(row)
        stop = should_stop is not None and should_stop()
        due = trainer.timesteps // cfg.checkpoint_every > (
            trainer.timesteps - cfg.batch_size) // cfg.checkpoint_every
        if due or stop or trainer.done:
            last_saved = save_checkpoint(trainer.state_dict(), out_dir, trainer.timesteps)
        if progress is not None:  # after the checkpoint: progress shown is progress kept
            progress(row)
        if stop:
            break
    return last_saved or find_checkpoint(out_dir)


def _check_new_dir(out_dir: Path) -> None:
    """Refuse to start a new run where one exists already."""
    if list_checkpoints(out_dir) or (out_dir / CONFIG_FILE).exists():
        raise InputError(f"{out_dir} already holds a run: resume it or choose another --out")


def _write_new_run(config: TrainConfig, advice: TreeDocument | AdviceFn | None,
                   out_dir: Path) -> None:
    """Create the run directory with ``config.json`` (and ``advice.json`` for a tree)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if isinstance(advice, TreeDocument):
        dump_tree(advice, out_dir / ADVICE_FILE)
    (out_dir / CONFIG_FILE).write_text(json.dumps(config.to_json(), indent=1) + "\n")


def _undo_new_run(out_dir: Path, existed: bool) -> None:
    """Remove what a failed start wrote, so that the same ``--out`` can be used again."""
    if not existed:
        shutil.rmtree(out_dir, ignore_errors=True)
        return
    for name in (CONFIG_FILE, ADVICE_FILE, METRICS_FILE):  # never what the caller made
        (out_dir / name).unlink(missing_ok=True)


def _resume_state(config: TrainConfig, out_dir: Path) -> dict[str, Any]:
    """The latest checkpoint of ``out_dir``, whose config must equal ``config``."""
    state = load_checkpoint(find_checkpoint(out_dir))
    saved = TrainConfig.from_json(state["config"])
    if saved != config:
        diff = sorted(k for k, v in config.to_json().items() if saved.to_json()[k] != v)
        raise InputError(f"cannot resume {out_dir}: config differs in {', '.join(diff)}")
    return state


def load_run_config(run_dir: Path) -> TrainConfig:
    """The ``config.json`` of a run directory."""
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise InputError(f"{run_dir} is not a training run (no {CONFIG_FILE})")
    try:
        return TrainConfig.from_json(json.loads(path.read_text()))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not valid JSON: {exc}") from exc


def load_run_advice(run_dir: Path) -> TreeDocument | None:
    """The advice tree saved with a run, or None."""
    path = Path(run_dir) / ADVICE_FILE
    return load_tree(path) if path.is_file() else None


def _advice_fn(config: TrainConfig, advice: TreeDocument | AdviceFn | None) -> AdviceFn | None:
    """F for the run; a tree must be over the run's env."""
    if advice is None:
        if config.uses_advice:
            raise InputError(f"--algo {config.algo} needs advice (an acv.tree/1 file)")
        return None
    if not isinstance(advice, TreeDocument):
        return advice
    if advice.env_id != config.env_id:
        raise InputError(f"the advice tree is for {advice.env_id}, but the run trains on "
                         f"{config.env_id}")
    return advice_reward(config, advice)


def advice_reward(config: TrainConfig, doc: TreeDocument) -> AdviceFn:
    """F built from a tree with the config's mode, depth factor and kappa."""
    return AdviceReward.from_tree(doc, mode=config.advice_mode,
                                  depth_factor=config.advice_depth_factor,
                                  kappa=config.advice_kappa)
