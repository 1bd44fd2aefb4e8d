"""H1 of docs/validation.md §6.8, declared after Hopper-v5's results and before any
Humanoid-v5 run of round 2 was measured: does the no-advice baseline's r spread wider than
the between-seed sd of 0.2 that round 2's design assumed?

Per advice bracket, r is the primary's per-run number (the Pearson r of the ``behaviour``
mean-similarity scores with the advice tree's T_r, as :func:`round2_analysis.arm_rows`) for
each ``n1`` seed; the test is the one-sided χ² test of their variance against 0.2². It reads
``round2.json``, ``advice/`` and ``n1``'s measures only, so it runs as soon as ``n1`` is
measured, before the other arms::

    python -m engine.validation.round2_spread docs/validation/round2-humanoid
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from engine.errors import InputError
from engine.validation.round2_analysis import PRIMARY, arm_measures, arm_rows, trees
from engine.validation.round2_runs import PLAN_FILE, Round2Plan
from engine.verdict_bracket import tree_values

#: The between-seed sd of r that round 2's power table assumed (§6.4).
ASSUMED_SD = 0.2
#: A bracket's spread is wider than assumed below this p.
ALPHA = 0.05
#: H1 is supported when this many brackets' spreads are.
SUPPORTING_BRACKETS = 2


@dataclass(frozen=True)
class Spread:
    """One advice bracket's baseline spread.

    Attributes:
        bracket: ``b0``, ``b1``, ...
        r: ``(seeds,)`` the ``n1`` seeds' r with the bracket's advice, in seed order.
        sd: Their sample sd (ddof 1).
        p_value: One-sided χ² test of the variance against :data:`ASSUMED_SD` squared.
    """

    bracket: str
    r: tuple[float, ...]
    sd: float
    p_value: float

    @property
    def wider(self) -> bool:
        """Whether the test rejects a spread of at most :data:`ASSUMED_SD`."""
        return self.p_value < ALPHA


def variance_test(r: np.ndarray, assumed_sd: float = ASSUMED_SD) -> tuple[float, float]:
    """``(sd, p)``: the sample sd of ``r`` and the one-sided χ² test of its variance against
    ``assumed_sd``², T = (n - 1) s² / σ², p = P(χ²ₙ₋₁ ≥ T)."""
    sd = float(np.std(r, ddof=1))
    statistic = (len(r) - 1) * sd**2 / assumed_sd**2
    return sd, float(stats.chi2.sf(statistic, df=len(r) - 1))


def baseline_spread(out: Path) -> list[Spread]:
    """Every advice bracket's :class:`Spread` of round 2's folder ``out``."""
    plan = Round2Plan(**json.loads((out / PLAN_FILE).read_text()))
    n1 = next(arm for arm in plan.design if arm.name == "n1")
    found = arm_measures(out, "n1", n1.seeds)
    spreads = []
    for b in range(plan.brackets):
        advice, shuffled = (tree_values(t) for t in trees(out, b))
        r = arm_rows(found, f"b{b}", advice, shuffled, PRIMARY, plan.teacher)[0]
        sd, p_value = variance_test(r)
        spreads.append(Spread(f"b{b}", tuple(float(x) for x in r), sd, p_value))
    return spreads


def supported(spreads: list[Spread]) -> bool:
    """H1's declared reading: the spread is wider on at least two brackets."""
    return sum(s.wider for s in spreads) >= SUPPORTING_BRACKETS


def main(argv: Sequence[str] | None = None) -> None:
    """Print H1's per-bracket result and its reading as JSON; exit 2 while ``n1`` is not
    measured."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="round 2's folder (round2.json, advice/, measures/)")
    args = parser.parse_args(argv)
    try:
        spreads = baseline_spread(args.out)
    except (InputError, FileNotFoundError) as exc:
        parser.exit(2, f"error: {exc}\n")
    found = {"brackets": [asdict(s) | {"wider": s.wider} for s in spreads]}
    print(json.dumps(found | {"supported": supported(spreads)}, indent=1))


if __name__ == "__main__":
    main()
