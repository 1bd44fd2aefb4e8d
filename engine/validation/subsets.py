"""What the product's verdict would have said with fewer seeds, read off a finished validation.

An experiment trains its advised arm and its no-advice baseline on the same seeds. Of every
way to pick ``k`` of a validation's seeds (the same seed indices in both arms), this counts
how often the verdict's test on the advice's own bracket says "used" or "went against": the
power of a ``k``-seed experiment measured on real runs instead of a model (issue 25 asks
for a positive control at 4 seeds). The per-seed CA on bracket 0 is what the verdict tests:
the pilots pick the contested matches, so they are the same for every subset. ``acv validate``
writes this into ``summary.json``; for a summary written before, read it off the file::

    PYTHONPATH=. .venv/bin/python -m engine.validation.subsets \
        docs/validation/hopper-orthogonal/summary.json
"""

from __future__ import annotations

import itertools
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from engine.validation.design import BASELINE
from engine.verdict import VerdictOptions
from engine.verdict_power import permutation_p, smallest_p

OPTIONS = VerdictOptions()
#: Seeds per arm looked at: issue 25's positive control (4), the product's default (5).
SEED_COUNTS = (4, 5)


def subset_outcomes(
    advised: np.ndarray, baseline: np.ndarray, k: int, rng: np.random.Generator
) -> dict[str, Any]:
    """The verdict's test on every choice of ``k`` matched seeds.

    Args:
        advised: each seed's CA on the advice's bracket, shape ``(seeds,)``.
        baseline: the same seeds' CA of the no-advice arm, shape ``(seeds,)``.
        k: seeds per arm in each subset.
        rng: draws the relabellings of a Monte Carlo test (never at these sizes: exact).

    Returns:
        ``subsets`` (how many), the shares saying ``used`` and ``against`` (p ≤ 0.05 and Δ
        of that sign), ``smallest_p`` (the floor of the exact test at ``k`` against ``k``).
    """
    combos = np.array(list(itertools.combinations(range(len(advised)), k)))
    a, b = advised[combos], baseline[combos]
    rejects = permutation_p(a, b, rng) <= OPTIONS.alpha
    delta = a.mean(axis=1) - b.mean(axis=1)
    return {
        "k": k,
        "subsets": len(combos),
        "used": float(np.mean(rejects & (delta > 0))),
        "against": float(np.mean(rejects & (delta < 0))),
        "smallest_p": smallest_p(k, k),
    }


def summary_subsets(
    summary: dict[str, Any], seed_counts: tuple[int, ...] = SEED_COUNTS
) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """Per judge and arm (every arm but the baseline), :func:`subset_outcomes` at each count of
    seeds and at all of them, from ``summary.json``'s per-seed CA on bracket 0. An arm whose
    verdict had too few contested matches to count (it "cannot tell" with any seeds; only
    summaries that record the count say so) is left out, as is one with none at all."""
    rng = np.random.default_rng(0)
    found: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for judge, result in summary["judges"].items():
        ca = {arm: np.array(rows, dtype=float)[:, 0] for arm, rows in result["ca"].items()}
        seeds = len(ca[BASELINE])
        counts = sorted({*(k for k in seed_counts if k < seeds), seeds})
        found[judge] = {
            arm: [subset_outcomes(ca[arm], ca[BASELINE], k, rng) for k in counts]
            for arm in ca
            if arm != BASELINE and not np.isnan(ca[arm]).any() and _countable(result, arm)
        }
    return found


def _countable(result: dict[str, Any], arm: str) -> bool:
    contested = result.get("verdicts", {}).get(arm, {}).get("contested")
    return contested is None or contested >= OPTIONS.min_contested


def table(found: dict[str, dict[str, list[dict[str, Any]]]]) -> str:
    """A Markdown table: per judge and arm, the share of subsets saying "used" at each k."""
    lines = [
        "| judge | arm | k | subsets | used | went against |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for judge, arms in found.items():
        for arm, rows in arms.items():
            for r in rows:
                lines.append(
                    f"| {judge} | {arm} | {r['k']} | {r['subsets']} | {r['used']:.2f} | "
                    f"{r['against']:.2f} |"
                )
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    summary = json.loads(Path(argv[0]).read_text())
    found = summary_subsets(summary)
    print(table(found))
    print(json.dumps({"summary": argv[0], "alpha": OPTIONS.alpha, "subsets": found}))


if __name__ == "__main__":  # pragma: no cover
    main(sys.argv[1:])
