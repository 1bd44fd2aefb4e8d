"""Reliability-weighted pooling against the plain mean, on simulated crowds whose truth is
known (issue 28 §2; docs/method.md §2.13).

One Humanoid-v5 study (16 uniform candidates, p = 0.9, seed 0); each replicate crowd labels
its bracket: 7 `standing` teachers and 6 `orthogonal` (arms raised) teachers, each deciding
with taste noise 0.1, 3 random clickers and 2 always-left clickers (sides are drawn per match,
so on the bracket they click at random too). Each also answers 4 gold items (a careful
participant errs with probability 0.05, a clicker is right half the time) and 3 consistency
pairs (a bracket match asked again with its sides swapped: a careful participant agrees
unless one of the two decisions flips, an always-left clicker never agrees).

Per crowd, the whole crowd is pooled twice, by the plain mean of F and weighted by each
person's MACE competence (:mod:`engine.reliability`), and each pooled tree is compared with
each taste's noise-free tree (match agreement). Reported over the crowds: the mean agreement
per taste and method, the paired difference with a 95% bootstrap interval, and each group's
share of the total weight (the plain mean gives each person 1/18).

    PYTHONPATH=. .venv/bin/python -m benchmarks.crowd_reliability [--crowds 200]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy.stats import bootstrap

from engine.crowd_sim import CROWD, TASTES, noise_free_tree, one_crowd
from engine.pipeline import run_tournament


def interval(values: np.ndarray, rng: np.random.Generator) -> list[float]:
    """The mean and its 95% bootstrap (BCa) interval over the crowds."""
    ci = bootstrap((values,), np.mean, rng=rng).confidence_interval
    return [float(np.mean(values)), float(ci.low), float(ci.high)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--crowds", type=int, default=200)
    args = parser.parse_args()
    base = run_tournament(env_id="Humanoid-v5", n_candidates=16, p=0.9, seed=0, teacher="standing")
    truth = {taste: noise_free_tree(base, taste) for taste in TASTES}
    rng = np.random.default_rng(2026)
    rows = [one_crowd(base, truth, rng) for _ in range(args.crowds)]

    def col(key: str) -> np.ndarray:
        return np.array([row[key] for row in rows])

    result = {key: interval(col(key), rng) for key in rows[0]} | {
        f"weighted-plain/{taste}": interval(col(f"weighted/{taste}") - col(f"plain/{taste}"), rng)
        for taste in TASTES
    }
    for key, (mean, low, high) in result.items():
        print(f"{key:28} {mean:.3f} [{low:.3f}, {high:.3f}]")
    print(json.dumps({"crowds": args.crowds, "crowd": CROWD, "result": result}))


if __name__ == "__main__":
    main()
