"""``acv reproduce``: the paper's experiments (section V) on one shared candidate set and bracket.

Every agent ("arm") trains on the same env and is compared with one advice tree over the same
bracket:

- ``ppo``: no advice, the baseline (compared with the ``standing`` tree);
- ``case1-paper``: ``bipars-em`` with F = R, the env's own step reward (the paper's Case 1,
  "good advice"), compared with the ``good`` tree;
- ``case1-tree``: ``bipars-em`` with F made from the ``good`` teacher's tree;
- ``case2``: ``bipars-em`` with ``standing`` advice (the paper's Case 2);
- ``case2-mgl``: ``bipars-mgl`` (meta-gradient) with ``standing`` advice;
- ``control``: ``ppo-shaped`` with ``standing`` advice (z = 1: what naive shaping gives);
- ``case2-paper-min``, ``case2-paper-depth``: Case 2 with the paper's literal F
  (``paper-min``) and with its depth factor, an ablation.

Core arms train ``seeds`` seeds, the others ``extra_seeds``. The output folder holds
``reproduce.json`` (the configuration; a second call with the same one resumes),
``advice/{good,standing}.json`` and ``runs/<arm>/seed_<k>/`` (ordinary training runs, see
:mod:`engine.rl.runner`). Training is resumed from the last checkpoint of every unfinished
run, so an interrupted reproduction loses at most one checkpoint period.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from app.reproduce.arms import ARMS, Arm
from engine.envs import DEFAULT_ENV_ID
from engine.errors import InputError
from engine.pinned import pin_settings
from engine.pipeline import replay_with_teacher, run_tournament
from engine.treefile import TreeDocument, dump_tree, load_tree

CONFIG_FILE = "reproduce.json"


@dataclass(frozen=True)
class ReproduceConfig:
    """What ``acv reproduce`` runs; saved as ``reproduce.json`` and checked on resume."""

    env_id: str = DEFAULT_ENV_ID
    """Gymnasium MuJoCo env."""
    timesteps: int = 1_000_000
    """Env steps per agent and seed."""
    seeds: int = 1
    """Training seeds of each core arm: 0, 1, ..., seeds - 1."""
    extra_seeds: int = 1
    """Training seeds of the other arms (at most ``seeds``)."""
    n_envs: int = 4
    """Parallel envs per run."""
    num_steps: int = 512
    """Steps per env per rollout."""
    checkpoint_every: int = 50_000
    """Checkpoint period in env steps: the Agent Preference Tree is extracted at each."""
    candidates: int = 16
    """Candidate states in the shared bracket."""
    p: float = 0.9
    """Braverman-Mossel coin probability of the shared bracket."""
    bracket_seed: int = 0
    """Seed of the candidate sampling and bracket seeding."""
    study_id: int | None = None
    """With ``participant_id``: a real participant's tree replaces the ``standing`` advice."""
    participant_id: int | None = None
    """The participant of ``study_id`` whose Human Preference Tree is used."""

    def __post_init__(self) -> None:
        for name in (
            "timesteps",
            "seeds",
            "extra_seeds",
            "n_envs",
            "num_steps",
            "checkpoint_every",
        ):
            if getattr(self, name) < 1:
                raise InputError(
                    f"--{name.replace('_', '-')} must be at least 1, got {getattr(self, name)}"
                )
        if self.candidates < 2:
            raise InputError(f"--candidates must be at least 2, got {self.candidates}")
        if not 0.0 <= self.p <= 1.0:
            raise InputError(f"--p must be in [0, 1], got {self.p}")
        if (self.study_id is None) != (self.participant_id is None):
            raise InputError("--study and --participant go together")

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, obj: dict) -> ReproduceConfig:
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in obj.items() if k in known})


def prepare(
    out: Path, config: ReproduceConfig, participant_tree: TreeDocument | None = None
) -> dict[str, TreeDocument]:
    """Write or check ``reproduce.json`` and return the advice trees by name.

    Args:
        participant_tree: the real participant's tree when ``config`` names one.

    Raises:
        InputError: ``out`` holds a reproduction with another configuration.
    """
    pin_settings(
        out / CONFIG_FILE,
        config.to_json(),
        "a reproduction",
        normalize=lambda saved: ReproduceConfig.from_json(saved).to_json(),
    )
    return advice_trees(out, config, participant_tree)


def advice_trees(
    out: Path, config: ReproduceConfig, participant_tree: TreeDocument | None = None
) -> dict[str, TreeDocument]:
    """``good`` and ``standing`` advice over one bracket (made once, then reloaded)."""
    folder = out / "advice"
    if (folder / "standing.json").is_file() and (folder / "good.json").is_file():
        return {name: load_tree(folder / f"{name}.json") for name in ("good", "standing")}
    standing = participant_tree or run_tournament(
        env_id=config.env_id,
        n_candidates=config.candidates,
        p=config.p,
        seed=config.bracket_seed,
        teacher="standing",
    )
    trees = {"good": replay_with_teacher(standing, "good"), "standing": standing}
    folder.mkdir(parents=True, exist_ok=True)
    for name, doc in trees.items():
        dump_tree(doc, folder / f"{name}.json")
    return trees


def run_path(out: Path, arm: Arm, seed: int) -> Path:
    """``<out>/runs/<arm>/seed_<seed>``."""
    return out / "runs" / arm.name / f"seed_{seed}"


def train_config(config: ReproduceConfig, arm: Arm, seed: int):
    """The :class:`engine.rl.config.TrainConfig` of one arm and seed."""
    from engine.rl.config import TrainConfig

    return TrainConfig(
        algo=arm.algo,
        env_id=config.env_id,
        total_timesteps=config.timesteps,
        seed=seed,
        n_envs=config.n_envs,
        num_steps=config.num_steps,
        checkpoint_every=config.checkpoint_every,
        advice_mode=arm.advice_mode,
        advice_depth_factor=arm.depth_factor,
    )


def arm_seeds(config: ReproduceConfig, arm: Arm) -> range:
    """The training seeds of ``arm``."""
    return range(config.seeds if arm.core else min(config.extra_seeds, config.seeds))


def tasks(config: ReproduceConfig) -> list[tuple[Arm, int]]:
    """Every (arm, seed) to train, seed by seed (so that seed 0 of every arm comes first)."""
    return [
        (arm, seed)
        for seed in range(config.seeds)
        for arm in ARMS
        if seed in arm_seeds(config, arm)
    ]


def train_all(
    out: Path, config: ReproduceConfig, trees: dict[str, TreeDocument], jobs: int = 1
) -> None:
    """Train (or finish training) every arm and seed, ``jobs`` runs at a time."""
    todo = tasks(config)
    if jobs <= 1:
        for i, (arm, seed) in enumerate(todo):
            train_arm(out, config, arm, seed, trees, i)
        return
    # Runs are independent and single-threaded (torch uses one thread per run): processes
    # give a near-linear speed-up; spawn, because torch and MuJoCo are not fork-safe.
    with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
        futures = [
            pool.submit(train_arm, out, config, arm, seed, trees, i % jobs)
            for i, (arm, seed) in enumerate(todo)
        ]
        for future in futures:
            future.result()


def train_arm(
    out: Path,
    config: ReproduceConfig,
    arm: Arm,
    seed: int,
    trees: dict[str, TreeDocument],
    position: int = 0,
) -> None:
    """Train one arm and seed to the end, resuming from its last checkpoint if it has one."""
    from engine.rl.checkpoint import list_checkpoints
    from engine.rl.runner import train

    cfg = train_config(config, arm, seed)
    path = run_path(out, arm, seed)
    done = cfg.num_updates * cfg.batch_size
    found = list_checkpoints(path)
    if found and max(found) >= done:
        return
    if not found and path.exists():  # killed before its first checkpoint: start again
        shutil.rmtree(path)
    with _progress_bar(arm, seed, done, max(found) if found else 0, position) as progress:
        train(
            cfg,
            trees[arm.advice] if arm.advice else None,
            path,
            progress=progress,
            resume=bool(found),
        )


@contextmanager
def _progress_bar(
    arm: Arm, seed: int, total: int, start: int, position: int
) -> Iterator[Callable[[dict[str, Any]], None]]:
    """A progress bar for one arm and seed, and the callback that moves it per update."""
    from tqdm import tqdm

    with tqdm(
        total=total,
        initial=start,
        unit="step",
        position=position,
        leave=True,
        desc=f"{arm.name} seed {seed}",
        dynamic_ncols=True,
    ) as bar:

        def progress(row: dict[str, Any]) -> None:
            bar.update(row["timesteps"] - bar.n)
            ret = row.get("return_100")
            bar.set_postfix(
                ret="-" if ret is None else f"{ret:.0f}", z=f"{row['z_mean']:.2f}", refresh=False
            )

        yield progress
