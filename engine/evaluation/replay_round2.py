"""The replay on round 2's committed runs (docs/validation.md §7.5, issue 41 §4).

The same simulated evaluators, design, criteria and seeds as round 1's replay
(:mod:`engine.evaluation.replay`), on the U of round 2's runs (``truth`` in
``docs/validation/round2-<env>/measures/<label>-<seed>.json``, one value per teacher). Each
arm of 5 runs (a label such as ``p1-10.b0``) is compared with ``n1``'s first 5 seeds, the
ones the product's verdict reads (§6.4). What round 2 adds is the **unrelated taste as the
issue means it**: on Humanoid-v5 every run's U is measured under the ``standing`` teacher
too, so the taste evaluator reads the ``standing`` U of the same 10 runs (fixed, not drawn
per replay), and its own test is U's exact test under ``standing``. On an env without a
second teacher (Hopper-v5) there is no taste evaluator.

Arms with fewer than 5 measured runs (round 2 still training) are listed as pending, never
replayed. Simulated evaluators check statistics and plumbing, never that people see the
difference.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.evaluation.replay import (
    BASELINE,
    JUDGES,
    N_BOOT,
    REPLAYS,
    RUNS_PER_ARM,
    SEED,
    TEACHER,
    Judge,
    replay_arm,
    write_result,
)

#: The teacher whose U is the ground truth, and the unrelated one the taste evaluator reads.
TRUTH, TASTE = "orthogonal", "standing"
PILOT = "pilot"
STANDING_TASTE = Judge(
    "standing-taste", TEACHER, "the teacher on each run's U under the standing teacher "
    "(round 2 measures both for every Humanoid-v5 run)", reads_taste=True,
)  # fmt: skip
#: Round 1's evaluators without its stand-in taste (scores independent of the arms).
PLAIN_JUDGES = tuple(j for j in JUDGES if not j.reads_taste)


@dataclass(frozen=True)
class Round2Arm:
    """One arm of round 2 against ``n1``'s first 5 seeds.

    Attributes:
        label: the runs' label, ``p1-10.b0``.
        u: shape ``(10,)``: the arm's 5 runs' U under :data:`TRUTH` by seed, then ``n1``'s.
        taste: shape ``(10,)``: the same runs' U under :data:`TASTE`, or ``None``.
    """

    label: str
    u: np.ndarray
    taste: np.ndarray | None


def load_truths(folder: Path) -> dict[str, list[dict[str, float]]]:
    """Every measured run's U per teacher, by label, in seed order (pilots left out)."""
    runs: dict[str, list[tuple[int, dict[str, float]]]] = {}
    for path in folder.glob("*.json"):
        label, seed = path.stem.rsplit("-", 1)
        if label != PILOT:
            truth = json.loads(path.read_text())["truth"]
            runs.setdefault(label, []).append((int(seed), truth))
    return {label: [t for _, t in sorted(found)] for label, found in sorted(runs.items())}


def round2_arms(folder: Path) -> tuple[list[Round2Arm], dict[str, int]]:
    """The arms ready to replay, and the pending ones with how many runs they have."""
    truths = load_truths(folder)
    baseline = truths.get(BASELINE, [])[:RUNS_PER_ARM]
    ready, pending = [], {}
    for label, runs in truths.items():
        if label == BASELINE:
            continue
        if len(runs) != RUNS_PER_ARM or len(baseline) != RUNS_PER_ARM:
            pending[label] = len(runs)
            continue
        both = runs + baseline
        u = np.array([t[TRUTH] for t in both])
        has_taste = all(TASTE in t for t in both)
        taste = np.array([t[TASTE] for t in both]) if has_taste else None
        ready.append(Round2Arm(label, u, taste))
    return ready, pending


def run_round2(
    folder: Path, env_id: str, replays: int = REPLAYS, seed: int = SEED, n_boot: int = N_BOOT
) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Every ready arm by every evaluator (the taste one where the runs have a taste's U)."""
    ready, pending = round2_arms(folder)
    out = []
    for arm in ready:
        judges = PLAIN_JUDGES + ((STANDING_TASTE,) if arm.taste is not None else ())
        key = f"{env_id}/{arm.label}"
        out.append(replay_arm(key, arm.u, judges, seed, replays, n_boot, arm.taste))
    return out, pending


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m engine.evaluation.replay_round2 --measures docs/validation/round2-humanoid/
    measures --env Humanoid-v5 --out docs/validation/evaluation/replay-round2-humanoid.json``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--measures", type=Path, required=True)
    parser.add_argument("--env", required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--replays", type=int, default=REPLAYS)
    parser.add_argument("--seed", type=int, default=SEED)
    raw = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(raw)
    start = time.perf_counter()
    arms_out, pending = run_round2(args.measures, args.env, args.replays, args.seed)
    command = " ".join(["python -m engine.evaluation.replay_round2", *raw])
    head = {"command": command, "replays": args.replays, "seed": args.seed}
    tail = {"baseline": f"{BASELINE}'s first {RUNS_PER_ARM} seeds", "pending": pending}
    write_result(args.out, arms_out, PLAIN_JUDGES + (STANDING_TASTE,), start, head, tail)


if __name__ == "__main__":
    main()
