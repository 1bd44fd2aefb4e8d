"""Every checkpoint of every run, judged once: the reproduction's per-checkpoint reports.

Two brackets are judged:

- ``main``: the shared advice bracket the agents trained on (candidates from random-policy
  rollouts), compared with each arm's advice tree (:attr:`Arm.compared_with`);
- ``agent``: a second bracket whose candidates come from the rollouts of the ``ppo`` arm's
  final checkpoint (seed 0), judged by the ``standing`` teacher. It answers "the candidates
  were only falling bodies": these are postures a trained agent reaches.

Each report (:class:`engine.rl.report.CheckpointReport`: every judge's tree and conformance,
and the per-candidate table) is cached as ``analysis/<bracket>/<arm>/seed_<k>/step_<N>.json``
in the output folder, so the report stage and a second call never recompute it.
"""

from __future__ import annotations

import json
import os
import tempfile
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

from app.reproduce.arms import ARMS, Arm
from app.reproduce.plan import ReproduceConfig, arm_seeds, run_path
from engine.treefile import TreeDocument, dump_tree, load_tree

BRACKETS: tuple[str, ...] = ("main", "agent")
AGENT_BRACKET_FILE = "agent-standing.json"
#: Seed of the second bracket's candidate rollouts and BM seeding.
AGENT_BRACKET_SEED = 1


def agent_bracket(out: Path, config: ReproduceConfig) -> TreeDocument:
    """The ``standing`` teacher's tree over candidates from the ``ppo`` arm's final policy
    (seed 0, deterministic actions); made once, then reloaded from ``advice/``."""
    from engine.pipeline import run_tournament
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.trained import deterministic_policy, load_agent

    path = out / "advice" / AGENT_BRACKET_FILE
    if path.is_file():
        return load_tree(path)
    ppo = next(arm for arm in ARMS if arm.name == "ppo")
    trained = load_agent(find_checkpoint(run_path(out, ppo, 0)))
    doc = run_tournament(
        env_id=config.env_id,
        n_candidates=config.candidates,
        p=config.p,
        seed=AGENT_BRACKET_SEED,
        teacher="standing",
        policy=deterministic_policy(trained),
    )
    dump_tree(doc, path)
    return doc


def report_path(out: Path, bracket: str, arm: Arm, seed: int, step: int) -> Path:
    """``<out>/analysis/<bracket>/<arm>/seed_<seed>/step_<step>.json``."""
    return out / "analysis" / bracket / arm.name / f"seed_{seed}" / f"step_{step}.json"


def bracket_trees(
    out: Path, config: ReproduceConfig, trees: dict[str, TreeDocument]
) -> dict[str, dict[str, TreeDocument]]:
    """The trees each bracket compares with, by bracket and advice name."""
    from engine.pipeline import replay_with_teacher

    standing = agent_bracket(out, config)
    return {
        "main": trees,
        "agent": {"standing": standing, "good": replay_with_teacher(standing, "good")},
    }


def arm_reports(out: Path, bracket: str, arm: Arm, seed: int, doc: TreeDocument) -> dict:
    """``{step: report JSON}`` at every checkpoint of one run, computing what is missing.

    Steps are those of the run's checkpoints and of the reports already cached: a run folder
    may keep only its last checkpoint once its reports are written (as a reproduction trained
    on another machine does).
    """
    from engine.rl.checkpoint import list_checkpoints
    from engine.rl.report import checkpoint_report

    run = run_path(out, arm, seed)
    folder = report_path(out, bracket, arm, seed, 0).parent
    cached = {int(p.stem.removeprefix("step_")): p for p in folder.glob("step_*.json")}
    reports = {}
    for step in sorted(set(list_checkpoints(run)) | set(cached)):
        if step in cached:
            reports[step] = json.loads(cached[step].read_text())
            continue
        reports[step] = checkpoint_report(run, step, doc).to_json()
        _write_atomic(report_path(out, bracket, arm, seed, step), json.dumps(reports[step]))
    return reports


def compute_reports(
    out: Path, config: ReproduceConfig, trees: dict[str, TreeDocument], jobs: int = 1
) -> None:
    """Judge every checkpoint of every run on both brackets, ``jobs`` runs at a time."""
    by_bracket = bracket_trees(out, config, trees)
    todo = [
        (bracket, arm, seed, by_bracket[bracket][arm.compared_with])
        for bracket in BRACKETS
        for arm in ARMS
        for seed in arm_seeds(config, arm)
    ]
    if jobs <= 1:
        for bracket, arm, seed, doc in todo:
            arm_reports(out, bracket, arm, seed, doc)
        return
    with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
        for future in [pool.submit(_reports_quietly, out, *task) for task in todo]:
            future.result()


def _reports_quietly(out: Path, bracket: str, arm: Arm, seed: int, doc: TreeDocument) -> None:
    """:func:`arm_reports` in a worker process (one torch thread: runs are many, nets tiny)."""
    import torch

    torch.set_num_threads(1)
    arm_reports(out, bracket, arm, seed, doc)


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)
