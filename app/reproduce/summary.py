"""One arm of a reproduction in numbers: per seed, then over seeds.

Over seeds, every number is a mean with a Student's t 95% interval
(:func:`app.reproduce.checkpoints.seed_statistics`): an interval over training seeds. The
Wilson interval of ``acv compare`` is another thing: an interval over the 15 matches of one
bracket for one agent, and says nothing about how another seed would have done.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from app.reproduce.analysis import seed_curve, training_stats
from app.reproduce.arms import Arm
from app.reproduce.checkpoints import BRACKETS, arm_reports
from app.reproduce.intervals import seed_statistics
from app.reproduce.plan import ReproduceConfig, arm_seeds, run_path
from engine.treefile import TreeDocument

#: The agent's judges summarised (of :data:`engine.judges.JUDGES`): those that every cached
#: report of a reproduction has (``return`` came later; ``value`` reads as ``shaped-value``).
JUDGES: tuple[str, ...] = ("shaped", "shaping", "shaped-value", "behaviour")
#: Per-judge numbers summarised over seeds.
JUDGE_KEYS: tuple[str, ...] = ("match_agreement", "contested_agreement", "bent_share")


def arm_entry(
    out: Path,
    config: ReproduceConfig,
    arm: Arm,
    docs: dict[str, dict[str, TreeDocument]],
    classes: dict[str, dict[int, str]],
) -> dict[str, Any]:
    """Everything measured of one arm: per-seed entries and statistics over seeds.

    Args:
        docs: bracket -> advice name -> the tree compared with.
        classes: bracket -> the posture class of each of its candidates.
    """
    seeds = [seed_entry(out, arm, seed, docs, classes) for seed in arm_seeds(config, arm)]
    return {
        "title": arm.title,
        "algo": arm.algo,
        "advice": arm.advice,
        "advice_mode": arm.advice_mode,
        "depth_factor": arm.depth_factor,
        "core": arm.core,
        "compared_with": arm.compared_with,
        "seeds": seeds,
        "final_return": seed_statistics([s["final_return_100"] for s in seeds]),
        "final": {b: {j: final_stats(seeds, b, j) for j in JUDGES} for b in BRACKETS},
        "curve": {b: {j: curve_stats(seeds, b, j) for j in JUDGES} for b in BRACKETS},
    }


def seed_entry(
    out: Path,
    arm: Arm,
    seed: int,
    docs: dict[str, dict[str, TreeDocument]],
    classes: dict[str, dict[int, str]],
) -> dict[str, Any]:
    """Training statistics and, per bracket, the conformance curve of one run."""
    entry: dict[str, Any] = {"seed": seed, **training_stats(run_path(out, arm, seed))}
    for bracket in BRACKETS:
        reports = arm_reports(out, bracket, arm, seed, docs[bracket][arm.compared_with])
        entry[bracket] = seed_curve(reports, classes[bracket])
    return entry


def final_stats(seeds: list[dict[str, Any]], bracket: str, judge: str) -> dict[str, Any]:
    """One judge at every seed's last checkpoint: statistics over seeds, and the counts."""
    finals = [s[bracket][-1]["judges"][judge] for s in seeds]
    out: dict[str, Any] = {
        key: seed_statistics([f[key] for f in finals], (0.0, 1.0)) for key in JUDGE_KEYS
    }
    out["step"] = [s[bracket][-1]["step"] for s in seeds]
    out["kept"] = [f"{f['n_agree']}/{f['n_matches']}" for f in finals]
    out["contested_kept"] = [f"{f['contested_kept']}/{f['contested_n']}" for f in finals]
    return out


def curve_stats(seeds: list[dict[str, Any]], bracket: str, judge: str) -> list[dict[str, Any]]:
    """One judge at every checkpoint all seeds have: statistics over seeds per step."""
    by_step = [{p["step"]: p["judges"][judge] for p in s[bracket]} for s in seeds]
    steps = sorted(set.intersection(*(set(b) for b in by_step))) if by_step else []
    return [
        {
            "step": step,
            **{
                key: seed_statistics([b[step][key] for b in by_step], (0.0, 1.0))
                for key in ("match_agreement", "contested_agreement")
            },
        }
        for step in steps
    ]
