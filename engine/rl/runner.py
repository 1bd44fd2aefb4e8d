"""A training run as a library call: ``train(config, advice, out_dir, ...)``.

The run directory holds ``config.json``, ``provenance.json`` (the ACV version, commit and
library versions that started it), ``metrics.jsonl`` (one row per update), TensorBoard
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
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeGuard

import torch

from engine.errors import InputError
from engine.provenance import PROVENANCE_FILE, provenance
from engine.rl.advice_fn import advice_reward, pool_reward
from engine.rl.checkpoint import find_checkpoint, list_checkpoints, load_checkpoint, save_checkpoint
from engine.rl.config import TrainConfig
from engine.rl.hparams import config_hparams
from engine.rl.logger import METRICS_FILE, RunLogger
from engine.rl.shaping import AdviceFn
from engine.rl.trainer import Trainer
from engine.treefile import TreeDocument, dump_tree, load_tree

CONFIG_FILE = "config.json"
ADVICE_FILE = "advice.json"
#: Pooled advice: every person's tree (``0.json``, ``1.json``, ...); ``advice.json`` then holds
#: the pooled verdict (:func:`engine.pooling.pooled_tree`).
POOL_DIR = "advice_pool"

Advice = TreeDocument | Sequence[TreeDocument] | AdviceFn | None
"""A run's advice: one tree, several trees over one bracket (pooled), an F callable, or none."""

Progress = Callable[[dict[str, Any]], None]
#: Called with (timesteps, path) after a checkpoint the run goes on from is written.
OnCheckpoint = Callable[[int, Path], None]


def train(
    config: TrainConfig,
    advice: Advice,
    out_dir: Path,
    progress: Progress | None = None,
    should_stop: Callable[[], bool] | None = None,
    resume: bool = False,
    on_checkpoint: OnCheckpoint | None = None,
    env_processes: int = 1,
) -> Path:
    """Train (or continue training) and return the path of the last checkpoint written.

    Args:
        config: the run's configuration.
        advice: a Human Preference Tree (F is built from it with the config's advice options
            and saved as ``advice.json``), a list of trees over one bracket (pooled: F is the
            mean of their F, weighted by ``config.pool_weights`` when set; saved in
            ``advice_pool/``), any F callable on ``qpos`` batches,
            or None (only for ``ppo``; on resume, the saved advice is reloaded).
        out_dir: the run directory (created).
        progress: called with every metrics row (``sps`` included).
        should_stop: polled after every update; True writes a checkpoint and returns.
        resume: continue from the latest checkpoint in ``out_dir``; the config must match.
        on_checkpoint: called after each checkpoint and its ``progress`` (not after the one
            a stop writes, so that stopping stays quick), e.g. to judge the checkpoint.
        env_processes: 2 for a lone run on an idle second core: half of the envs step in a
            helper process (:class:`engine.rl.split_vecenv.SplitVectorEnv`). Speed only: the
            metrics rows and checkpoints are the same as with 1, and it is not saved.

    Raises:
        InputError: missing or mismatched advice, an existing run without ``resume``, a
            resume without checkpoints or with another config, a corrupt checkpoint.
    """
    torch.set_num_threads(1)
    out_dir = Path(out_dir)
    if advice is None and resume:
        advice = load_run_pool(out_dir) or load_run_advice(out_dir)
    advice_fn = _advice_fn(config, advice)
    state = _resume_state(config, out_dir) if resume else None
    if not resume:
        _check_new_dir(out_dir)
    trainer, logger = _start(config, advice, advice_fn, out_dir, state, env_processes)
    try:
        return _loop(trainer, out_dir, logger, progress, should_stop, on_checkpoint)
    finally:
        logger.close()
        trainer.close()


def _start(
    config: TrainConfig,
    advice: Advice,
    advice_fn: AdviceFn | None,
    out_dir: Path,
    state: dict[str, Any] | None,
    env_processes: int = 1,
) -> tuple[Trainer, RunLogger]:
    """The trainer (restored from ``state`` on resume) and the logger of the run.

    The trainer (envs, networks: what bad input makes fail) is built before anything is
    written, and a new run's files are removed again if its start fails, so that a failed start
    never leaves a directory that refuses the next attempt as "already holds a run".
    """
    trainer = Trainer(config, advice_fn, env_processes)
    existed = out_dir.exists()
    try:
        if state is not None:
            trainer.load_state_dict(state)
        else:
            _write_new_run(config, advice, out_dir)
        return trainer, RunLogger(out_dir, trainer.timesteps, config_hparams(config))
    except BaseException:
        trainer.close()
        if state is None:
            _undo_new_run(out_dir, existed)
        raise


def _loop(
    trainer: Trainer,
    out_dir: Path,
    logger: RunLogger,
    progress: Progress | None,
    should_stop: Callable[[], bool] | None,
    on_checkpoint: OnCheckpoint | None = None,
) -> Path:
    """Iterate until done or stopped, checkpointing every ``checkpoint_every`` steps."""
    cfg = trainer.cfg
    start_steps, start_time = trainer.timesteps, time.perf_counter()
    last_saved = saved_now = None
    while not trainer.done:
        row = trainer.iterate()
        row["sps"] = (trainer.timesteps - start_steps) / (time.perf_counter() - start_time)
        logger.write(row)
        stop = should_stop is not None and should_stop()
        due = (
            trainer.timesteps // cfg.checkpoint_every
            > (trainer.timesteps - cfg.batch_size) // cfg.checkpoint_every
        )
        if due or stop or trainer.done:
            last_saved = saved_now = save_checkpoint(
                trainer.state_dict(), out_dir, trainer.timesteps
            )
        if progress is not None:  # after the checkpoint: progress shown is progress kept
            progress(row)
        if stop:
            break
        if saved_now is not None and on_checkpoint is not None:
            on_checkpoint(trainer.timesteps, saved_now)
        saved_now = None
    return last_saved or find_checkpoint(out_dir)


def _check_new_dir(out_dir: Path) -> None:
    """Refuse to start a new run where one exists already."""
    if list_checkpoints(out_dir) or (out_dir / CONFIG_FILE).exists():
        raise InputError(f"{out_dir} already holds a run: resume it or choose another --out")


def _write_new_run(config: TrainConfig, advice: Advice, out_dir: Path) -> None:
    """Create the run directory with ``config.json`` and ``provenance.json`` (and
    ``advice.json`` for a tree; the pool and its pooled verdict for several)."""
    from engine.pooling import pooled_tree

    out_dir.mkdir(parents=True, exist_ok=True)
    if isinstance(advice, TreeDocument):
        dump_tree(advice, out_dir / ADVICE_FILE)
    elif _is_pool(advice):
        (out_dir / POOL_DIR).mkdir(exist_ok=True)
        for i, doc in enumerate(advice):
            dump_tree(doc, out_dir / POOL_DIR / f"{i}.json")
        verdict = pooled_tree(advice, **config.tree_options(), weights=config.pool_weights)
        dump_tree(verdict, out_dir / ADVICE_FILE)
    (out_dir / CONFIG_FILE).write_text(json.dumps(config.to_json(), indent=1) + "\n")
    (out_dir / PROVENANCE_FILE).write_text(json.dumps(provenance(), indent=1) + "\n")


def _undo_new_run(out_dir: Path, existed: bool) -> None:
    """Remove what a failed start wrote, so that the same ``--out`` can be used again."""
    if not existed:
        shutil.rmtree(out_dir, ignore_errors=True)
        return
    # never what the caller made
    for name in (CONFIG_FILE, PROVENANCE_FILE, ADVICE_FILE, METRICS_FILE):
        (out_dir / name).unlink(missing_ok=True)
    shutil.rmtree(out_dir / POOL_DIR, ignore_errors=True)


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
    """The advice tree saved with a run (the pooled verdict for pooled advice), or None."""
    path = Path(run_dir) / ADVICE_FILE
    return load_tree(path) if path.is_file() else None


def load_run_pool(run_dir: Path) -> list[TreeDocument] | None:
    """The trees of a run trained on pooled advice, in order; None for any other run."""
    folder = Path(run_dir) / POOL_DIR
    paths = sorted(folder.glob("*.json"), key=lambda p: int(p.stem)) if folder.is_dir() else []
    return [load_tree(p) for p in paths] or None


def _is_pool(advice: Advice) -> TypeGuard[Sequence[TreeDocument]]:
    return isinstance(advice, list | tuple) and all(isinstance(d, TreeDocument) for d in advice)


def _advice_fn(config: TrainConfig, advice: Advice) -> AdviceFn | None:
    """F for the run; trees must be over the run's env."""
    _check_pool_weights(config, advice)
    if advice is None:
        if config.uses_advice:
            raise InputError(f"--algo {config.algo} needs advice (an acv.tree/1 file)")
        return None
    docs = (
        list(advice) if _is_pool(advice) else [advice] if isinstance(advice, TreeDocument) else None
    )
    if docs is None:
        return advice  # type: ignore[return-value]  # an F callable
    for doc in docs:
        if doc.env_id != config.env_id:
            raise InputError(
                f"the advice tree is for {doc.env_id}, but the run trains on {config.env_id}"
            )
    return advice_reward(config, docs[0]) if len(docs) == 1 else pool_reward(config, docs)


def _check_pool_weights(config: TrainConfig, advice: Advice) -> None:
    """Pool weights need pooled advice, one weight per tree."""
    weights = config.pool_weights
    if weights is None:
        return
    if not _is_pool(advice):
        raise InputError("pool weights need pooled advice: two or more advice trees")
    if len(weights) != len(advice):
        raise InputError(
            f"{len(weights)} pool weights for {len(advice)} pooled trees: give one per tree"
        )
