"""The verdict's positive control on Hopper-v5 (issue 25, "Done when"; docs/method.md §2.11).

Advice that is hard to ignore: ``ppo-shaped`` on the `orthogonal` teacher's tree (a bent
knee, which R does not pay for) at scale 10, against ``ppo`` with no advice, 4 seeds each.
Two pilot ``ppo`` runs on seeds of their own pick the contested matches. The same design
trained on a *shuffled* tree (the `random` teacher on the same bracket, a fair coin per
match) but judged against the real advice is the negative control. Issue 25 asks for "used
your advice" from the first and not from the second.

It prints each arm's verdict per judge and the ground truth: the teacher's own knee score
over 5 deterministic episodes per run, from reset seeds 10000-10004, which no judge uses.
Finished runs in ``--out`` (named ``<arm>-<seed>``) are reused, so a stopped run resumes.

With ``--eval-candidates N`` the verdicts are taken on a second bracket instead: N candidates
sampled in the ``informative`` mode from the first pilot's deterministic policy (a no-advice
run on seeds of its own), and the teacher's tree over them, the same taste as the advice the
runs trained on, asked on postures that a trained agent reaches.

    PYTHONPATH=. .venv/bin/python -m benchmarks.positive_control [--steps 245760] \\
        [--out /tmp/positive-control] [--jobs 2] [--eval-candidates 32]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from engine.informative import sample_informative
from engine.pipeline import replay_with_teacher, run_tournament, teacher_bracket
from engine.rl.checkpoint import find_checkpoint, list_checkpoints
from engine.rl.config import TrainConfig
from engine.rl.runner import train
from engine.rl.trained import deterministic_policy, load_agent
from engine.treefile import TreeDocument, dump_tree, load_tree
from engine.validation.measure import teacher_truth
from engine.verdict_runs import runs_verdict

ENV = "Hopper-v5"
SEEDS = (0, 1, 2, 3)
PILOT_SEEDS = (100, 101)
JUDGES = ("return", "behaviour", "shaped-value")


def train_run(algo: str, seed: int, advice: Path | None, out: Path, steps: int) -> Path:
    """One run (one torch thread), unless ``out`` already holds its last checkpoint."""
    if out.exists() and steps in list_checkpoints(out):
        return out
    config = TrainConfig(
        algo=algo, env_id=ENV, total_timesteps=steps, seed=seed, advice_scale=10.0,
        checkpoint_every=steps,
    )  # fmt: skip
    train(config, None if advice is None else load_tree(advice), out)
    return out


def train_arms(root: Path, steps: int, jobs: int) -> dict[str, list[Path]]:
    """The advice trees and every arm's runs, ``jobs`` at a time."""
    advice = run_tournament(env_id=ENV, n_candidates=16, p=0.9, seed=0, teacher="orthogonal")
    dump_tree(advice, root / "advice.json")
    dump_tree(replay_with_teacher(advice, "random"), root / "shuffled.json")
    plan: dict[str, list[tuple[str, int, Path | None]]] = {
        "advised": [("ppo-shaped", s, root / "advice.json") for s in SEEDS],
        "shuffled": [("ppo-shaped", s, root / "shuffled.json") for s in SEEDS],
        "baseline": [("ppo", s, None) for s in SEEDS],
        "pilot": [("ppo", s, None) for s in PILOT_SEEDS],
    }
    with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
        futures = {
            arm: [pool.submit(train_run, a, s, f, root / f"{arm}-{s}", steps) for a, s, f in runs]
            for arm, runs in plan.items()
        }
        return {arm: [f.result() for f in fs] for arm, fs in futures.items()}


def knee_score(run: Path, episodes: int = 5) -> float:
    """The `orthogonal` teacher's mean score over the run's deterministic episodes."""
    return teacher_truth(run, ENV, "orthogonal", episodes)


def evaluation_tree(pilot: Path, n_candidates: int) -> TreeDocument:
    """The teacher's tree over ``n_candidates`` states sampled in the ``informative`` mode
    from ``pilot``'s deterministic policy (seeded, apart from every training seed)."""
    rng = np.random.default_rng(20_000)
    policy = deterministic_policy(load_agent(find_checkpoint(pilot)))
    candidates = sample_informative(ENV, n_candidates, rng=rng, policy=policy)
    return teacher_bracket(ENV, candidates, rng, p=0.9, seed=20_000, teacher="orthogonal")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=245_760)
    parser.add_argument("--out", type=Path, default=Path("/tmp/positive-control"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--eval-candidates", type=int, default=0)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    runs = train_arms(args.out, args.steps, args.jobs)
    advice = load_tree(args.out / "advice.json")
    if args.eval_candidates:
        advice = evaluation_tree(runs["pilot"][0], args.eval_candidates)
        print(f"evaluation bracket: {args.eval_candidates} informative candidates", flush=True)
    for arm in ("advised", "shuffled", "baseline"):
        knees = " ".join(f"{knee_score(r):.2f}" for r in runs[arm])
        print(f"{arm}: knee score per seed {knees}", flush=True)
    for arm in ("advised", "shuffled"):
        for judge in JUDGES:
            found = runs_verdict(
                advice, (runs[arm], runs["baseline"], runs["pilot"]), judge,
                np.random.default_rng(0),
            )  # fmt: skip
            print(f"{arm} / {judge}: {found.outcome}: {found.text}", flush=True)


if __name__ == "__main__":
    main()
