"""How many of a bracket's matches can tell? ``uniform`` against ``informative`` candidates.

For each env, one short no-advice PPO baseline is trained once and cached (``--cache``): the
*sampling* baseline (seed 0), whose policy ``informative`` sampling rolls out, and a *judge*
baseline (seed 1), a no-advice run on another seed that stands in for the verdict's pilot
runs: its ``return`` judge (:mod:`engine.rl.returns`, default options: 5 perturbed rollouts
of at most 100 steps) picks the contested matches. With ``--judge-same`` the sampling
baseline judges too (cheaper, but then the estimate that placed the candidates also decides).

Then, per bracket seed, the study's pipeline as :func:`engine.pipeline.run_tournament` runs it
(one generator seeded with the bracket seed: candidates, BM first round, the teacher's
bracket), for each sampling mode, teacher and p. The matches of the teacher's bracket are
split as the verdict splits them (:func:`engine.verdict.split_matches`, default margins: 5%
of the advice scores' and of the judge scores' spread): *contested* (informative, and the
judge's winner is not the advice's), *agreed* (informative, same winner) and uninformative.
Issue 25's target: at least 8 contested as the minimum over the 5 bracket seeds, on both envs,
bracket and disagreement pairs together: after the bracket, up to ``--pairs`` pairs where the
teacher's tree (its heights, as a study knows a participant's) and the *sampling* baseline's
return disagree most clearly (:mod:`engine.disagreement`, as a study with
``disagreement_pairs`` picks them), which the teacher answers by its own score; the judge
baseline then splits bracket and pairs together, as an experiment's verdict does.

    PYTHONPATH=. .venv/bin/python -m benchmarks.informative_matches --env Hopper-v5 \\
        --env Humanoid-v5 [--seeds 0 1 2 3 4] [--teachers standing orthogonal] \\
        [--p 0.9 0] [--pairs 10] [--baseline-steps 100000] [--cache /tmp/informative]

It prints one row per env, teacher, mode and p: the contested count per seed, its minimum and
median, the informative (contested + agreed) minimum and median, then the contested count per
seed with the disagreement pairs and its minimum; the last line is JSON.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from engine.candidates import Policy
from engine.disagreement import disagreement_pairs
from engine.pipeline import sample_by_mode, teacher_bracket
from engine.treefile import TreeDocument
from engine.verdict import Pair, VerdictOptions, advice_scores, bracket_pairs, split_matches

TARGET = 8


def baseline(env_id: str, seed: int, steps: int, cache: Path) -> Policy:
    """The deterministic policy of a no-advice PPO run, trained once into ``cache``."""
    from engine.rl.checkpoint import find_checkpoint, list_checkpoints
    from engine.rl.config import TrainConfig
    from engine.rl.runner import train
    from engine.rl.trained import deterministic_policy, load_agent

    out = cache / env_id / ("baseline" if seed == 0 else f"pilot{seed}")
    if not list_checkpoints(out):
        start = time.time()
        config = TrainConfig(
            algo="ppo", env_id=env_id, total_timesteps=steps, seed=seed, checkpoint_every=steps
        )
        train(config, None, out)
        print(f"trained {out} in {time.time() - start:.0f} s", flush=True)
    return deterministic_policy(load_agent(find_checkpoint(out)))


def measure(args: argparse.Namespace) -> list[dict[str, Any]]:
    from engine.rl.returns import ReturnOptions, state_returns

    rows: list[dict[str, Any]] = []
    for env_id in args.env:
        sampler = baseline(env_id, 0, args.baseline_steps, args.cache)
        judge = sampler if args.judge_same else baseline(env_id, 1, args.baseline_steps, args.cache)
        counts: dict[tuple[str, str, float], list[tuple[int, int]]] = {}
        for seed in args.seeds:
            for mode in args.modes:
                start = time.time()
                rng = np.random.default_rng(seed)
                cands = sample_by_mode(
                    env_id,
                    args.candidates,
                    rng=rng,
                    mode=mode,
                    policy=sampler if mode == "informative" else None,
                )
                after_sampling = rng.bit_generator.state
                sample_s = time.time() - start
                qpos, qvel = np.stack([c.qpos for c in cands]), np.stack([c.qvel for c in cands])
                # the return judge's scores (engine.rl.returns.return_scores, uncached)
                pilot = state_returns(judge, env_id, qpos, qvel, ReturnOptions()).mean(axis=1)
                study_baseline = _sampler_returns(cands, sampler, env_id, qpos, qvel)
                for teacher in args.teachers:
                    for p in args.p:
                        rng.bit_generator.state = after_sampling  # as a study with this p
                        doc = teacher_bracket(env_id, cands, rng, p=p, seed=0, teacher=teacher)
                        bracket = split_matches(
                            advice_scores(doc), pilot, bracket_pairs(doc), VerdictOptions()
                        )
                        matches = bracket_pairs(doc) + answered_pairs(doc, study_baseline, args)
                        both = split_matches(advice_scores(doc), pilot, matches, VerdictOptions())
                        counts.setdefault((teacher, mode, p), []).append(
                            (
                                len(bracket.contested),
                                len(bracket.contested) + len(bracket.agreed),
                                len(both.contested),
                                len(matches) - len(bracket_pairs(doc)),
                            )
                        )
                print(
                    f"{env_id} seed {seed} {mode}: sampled in {sample_s:.1f} s, "
                    f"judged in {time.time() - start - sample_s:.1f} s",
                    flush=True,
                )
        for (teacher, mode, p), per_seed in counts.items():
            contested = [c for c, _, _, _ in per_seed]
            informative = [i for _, i, _, _ in per_seed]
            with_pairs = [w for _, _, w, _ in per_seed]
            rows.append(
                {
                    "env": env_id,
                    "teacher": teacher,
                    "mode": mode,
                    "p": p,
                    "contested": contested,
                    "contested_min": min(contested),
                    "contested_median": float(np.median(contested)),
                    "informative_min": min(informative),
                    "informative_median": float(np.median(informative)),
                    "pairs_asked": [n for _, _, _, n in per_seed],
                    "contested_with_pairs": with_pairs,
                    "contested_with_pairs_min": min(with_pairs),
                    "target_met_by_the_bracket": min(contested) >= TARGET,
                    "target_met": min(with_pairs) >= TARGET,
                }
            )
    return rows


def _sampler_returns(
    cands: list[Any], sampler: Policy, env_id: str, qpos: np.ndarray, qvel: np.ndarray
) -> np.ndarray:
    """The sampling baseline's return from each candidate, as a study stores it
    (``app.studies.baseline.baseline_returns``): the ``informative`` estimate where
    sampling made one, else the return judge's rollouts."""
    from engine.rl.returns import ReturnOptions, state_returns

    if all(c.seed_score is not None for c in cands):
        return np.array([c.seed_score for c in cands], dtype=float)
    return state_returns(sampler, env_id, qpos, qvel, ReturnOptions()).mean(axis=1)


def answered_pairs(
    doc: TreeDocument, study_baseline: np.ndarray, args: argparse.Namespace
) -> tuple[Pair, ...]:
    """The disagreement pairs a study would ask after this bracket, answered by the teacher's
    own score (the tree records it; a tie keeps the advice's pick)."""
    heights = np.array([doc.tree.nodes[c.id].height for c in doc.candidates], dtype=float)
    played = [(a, b) for a, b, _ in bracket_pairs(doc)]
    pairs = disagreement_pairs(heights, study_baseline, k=args.pairs, played=played)
    score = advice_scores(doc)
    return tuple((a, b, b if score[b] > score[a] else a) for a, b in pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", action="append", required=True, help="repeat for several")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--teachers", nargs="+", default=["standing", "orthogonal"])
    parser.add_argument("--modes", nargs="+", default=["uniform", "informative"])
    parser.add_argument("--p", type=float, nargs="+", default=[0.9, 0.0])
    parser.add_argument("--candidates", type=int, default=16)
    parser.add_argument("--pairs", type=int, default=10, help="disagreement pairs (0..10)")
    parser.add_argument("--baseline-steps", type=int, default=100_000)
    parser.add_argument("--cache", type=Path, default=Path("/tmp/informative"))
    parser.add_argument("--judge-same", action="store_true")
    args = parser.parse_args()
    rows = measure(args)
    print()
    print(
        f"{'env':<12} {'teacher':<10} {'mode':<11} {'p':>4}  {'contested per seed':<22}"
        f"{'min':>4} {'median':>7}  {'informative min/median':>22}  "
        f"{'with pairs per seed':<22}{'min':>4}"
    )
    for r in rows:
        print(
            f"{r['env']:<12} {r['teacher']:<10} {r['mode']:<11} {r['p']:>4g}  "
            f"{' '.join(map(str, r['contested'])):<22}{r['contested_min']:>4} "
            f"{r['contested_median']:>7g}  "
            f"{r['informative_min']:>15} / {r['informative_median']:<4g}  "
            f"{' '.join(map(str, r['contested_with_pairs'])):<22}{r['contested_with_pairs_min']:>4}"
        )
    print(json.dumps({"target": TARGET, "rows": rows}))


if __name__ == "__main__":
    main()
