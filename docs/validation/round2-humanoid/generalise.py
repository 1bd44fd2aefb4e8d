"""Round 2's reports on Humanoid-v5 written after its results (docs/validation.md §6.9):
descriptions, never deciding.

- `rows`, generalisation (declared as reported in §6.5): each advised arm's whole-bracket r,
  by the primary score, on the advice brackets it never trained on, against `n1`'s seeds
  100-104 there.
- `other_baseline`: each deciding arm's verdict on its own bracket against `n1`'s other five
  seeds (105-109) instead of the declared 100-104 (read after the results).

With the frozen round-2 code (ef285ec) on the path, as the declared analysis ran:

    PYTHONPATH=/work/round2-code python docs/validation/round2-humanoid/generalise.py \
        docs/validation/round2-humanoid > docs/validation/round2-humanoid/generalisation.json
"""

import json
import sys
from pathlib import Path

import numpy as np

from engine.validation.round2_analysis import PRIMARY, _scores, trees
from engine.verdict_bracket import alignment_verdict, tree_values

TRAINED_ON = {"p1-10": 3, "bipars-em": 2}  # advice brackets each advised arm trained on


def row(out: Path, arm: str, own: int, other: int, rng: np.random.Generator) -> dict:
    values = tree_values(trees(out, other)[0])
    base = _scores(out, "n1", 5, f"b{other}", PRIMARY)
    runs = _scores(out, f"{arm}.b{own}", 5, f"b{other}", PRIMARY)
    found = alignment_verdict(values, runs, base, rng, stage="diagnostic")
    return {
        "arm": f"{arm}.b{own}",
        "judged_on": f"b{other}",
        "delta": round(found.delta, 3),
        "interval": [round(x, 3) for x in found.interval],
        "p_value": round(found.p_value, 4),
        "r_advised_mean": round(float(np.mean(found.r_advised)), 3),
        "r_baseline_mean": round(float(np.mean(found.r_baseline)), 3),
    }


def against_other_seeds(out: Path, arm: str, own: int, rng: np.random.Generator) -> dict:
    values = tree_values(trees(out, own)[0])
    found = alignment_verdict(
        values, _seeds(out, arm, own, range(100, 105)), _seeds(out, "n1", own, range(105, 110)), rng
    )
    return {
        "arm": f"{arm}.b{own}",
        "outcome": found.outcome,
        "delta": round(found.delta, 3),
        "interval": [round(x, 3) for x in found.interval],
        "p_value": round(found.p_value, 4),
        "r_baseline": [round(x, 3) for x in found.r_baseline],
    }


def _seeds(out: Path, arm: str, own: int, seeds: range) -> np.ndarray:
    label = arm if arm == "n1" else f"{arm}.b{own}"
    paths = [out / "measures" / f"{label}-{s}.json" for s in seeds]
    return np.array([json.loads(p.read_text())["scores"][f"b{own}"][PRIMARY] for p in paths])


def main() -> None:
    out, rng = Path(sys.argv[1]), np.random.default_rng(0)
    rows = [
        row(out, arm, own, other, rng)
        for arm, brackets in TRAINED_ON.items()
        for own in range(brackets)
        for other in range(3)
        if other != own
    ]
    deciding = {"p1-10": 3, "bipars-em": 2, "n2-10": 3}
    other = [
        against_other_seeds(out, arm, own, rng)
        for arm, brackets in deciding.items()
        for own in range(brackets)
    ]
    command = __doc__.split("\n\n")[-1].strip()
    print(json.dumps({"command": command, "rows": rows, "other_baseline": other}, indent=1))


if __name__ == "__main__":
    main()
