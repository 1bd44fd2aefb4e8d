"""Power of round 2's criteria at its design, by simulation (docs/validation.md §6.4).

A simulated round draws, per advice bracket, each run's alignment ``r`` with the bracket's
advice and with its shuffled tree, and each run's ground truth U:

- ``r = bracket base + arm shift + seed effect`` (seed sd 0.2: round 1's ``n1``); the
  advised arms' shift is ``effect``, ``n3``'s ``-effect / 2``, the shuffled and ``n1``
  arms' 0. Against the shuffled tree, the shuffled arm has the shift ``effect`` instead
  and the advised arms 0 (the trees are drawn unrelated);
- ``U = gain * (shift + seed effect) + noise`` (gain 0.6 = round 1's ΔU / Δr for
  ``p1-10``, 0.31 / 0.52; noise sd 0.05), so U and ``r`` share each seed's effect as round 1's
  ρ(Δ, ΔU) = 0.70 suggests.

Round 1's measured effect was found after the fact, so the table gives it and its half.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import binomtest, spearmanr

from engine.validation.round2 import known_direction
from engine.verdict_power import auc, permutation_p

ARMS = {"p1-10": 1.0, "n2-10": 0.0, "bipars-em": 1.0, "n3": -0.5}
#: The arms on each of round 2's three Humanoid brackets (``n1`` is on all).
ON_BRACKET = (
    ("p1-10", "n2-10", "bipars-em", "n3"),
    ("p1-10", "n2-10", "bipars-em"),
    ("p1-10", "n2-10"),
)


@dataclass(frozen=True)
class Model:
    """Spreads of the simulated round (module docstring)."""

    seed_sd: float = 0.2
    bracket_sd: float = 0.1
    gain: float = 0.6
    truth_sd: float = 0.05


def _bracket(
    effect: float,
    arms: tuple[str, ...],
    n1_effects: np.ndarray,
    model: Model,
    rng: np.random.Generator,
) -> dict[str, np.ndarray]:
    """Per arm ``(r_own, r_shuffled, U)`` of each seed, shape ``(3, seeds)``."""
    base = rng.normal(0, model.bracket_sd, 2)
    drawn = {"n1": _runs(0.0, 0.0, n1_effects, base, model, rng)}
    for arm in arms:
        shift = effect * ARMS[arm]
        other = effect if arm == "n2-10" else 0.0
        drawn[arm] = _runs(shift, other, rng.normal(0, model.seed_sd, 5), base, model, rng)
    return drawn


def _runs(
    shift: float,
    other: float,
    seed: np.ndarray,
    base: np.ndarray,
    model: Model,
    rng: np.random.Generator,
) -> np.ndarray:
    own = base[0] + shift + seed
    shuffled = base[1] + other + rng.normal(0, model.seed_sd, len(seed))
    truth = model.gain * (shift + seed) + rng.normal(0, model.truth_sd, len(seed))
    return np.stack([own, shuffled, truth])


def simulate(effect: float, model: Model, rng: np.random.Generator) -> list[dict[str, np.ndarray]]:
    """One simulated round: per bracket, per arm, ``(3, seeds)``; ``n1``'s 10 seeds shared."""
    n1 = rng.normal(0, model.seed_sd, 10)
    return [_bracket(effect, arms, n1, model, rng) for arms in ON_BRACKET]


def _call(arm: np.ndarray, n1: np.ndarray, rng: np.random.Generator) -> str:
    """The product's verdict: the arm's 5 seeds against ``n1``'s first 5, exact test."""
    p = float(permutation_p(arm[0], n1[0, :5], rng))
    delta = arm[0].mean() - n1[0, :5].mean()
    return "no-different" if p > 0.05 else ("used" if delta > 0 else "against")


def criteria(round_: list[dict[str, np.ndarray]], rng: np.random.Generator) -> dict[str, bool]:
    """Whether C1, C3, C4, C5, C7 and C8 pass (the C1 interval left to the bootstrap of
    :func:`separation_low`)."""
    aucs = [auc(b["p1-10"][0], np.concatenate([b["n1"][0], b["n2-10"][0]])) for b in round_]
    rhos = [_rho(b) for b in round_]
    shuffled_calls = [_call(b["n2-10"], b["n1"], rng) for b in round_]
    against = sum(c == "against" for c in shuffled_calls)
    c7 = all(
        _call(b["bipars-em"], b["n1"], rng) == "used"
        for b in round_
        if "bipars-em" in b and known_direction(b["bipars-em"][2], b["n1"][2]) == "follows"
    )
    return {
        "C1": bool(np.mean(aucs) >= 0.9 and separation_low(round_, rng) >= 0.75),
        "C3": bool(np.mean(rhos) >= 0.7),
        "C4": _call(round_[0]["n3"], round_[0]["n1"], rng) == "against",
        "C5": "used" not in shuffled_calls
        and binomtest(against, len(round_), 0.05, alternative="greater").pvalue > 0.05,
        "C7": c7,
        "C8": _sign(round_, "p1-10", 1) and _sign(round_, "n2-10", -1),
    }


def _rho(b: dict[str, np.ndarray]) -> float:
    n1 = b["n1"]
    runs = [b[a] for a in b if a != "n1"]
    delta = np.concatenate([r[0] - n1[0].mean() for r in runs])
    delta_u = np.concatenate([r[2] - n1[2].mean() for r in runs])
    return float(spearmanr(delta, delta_u).statistic)


def _sign(round_: list[dict[str, np.ndarray]], arm: str, side: int) -> bool:
    diffs = np.concatenate([side * (b[arm][0] - b[arm][1]) for b in round_])
    test = binomtest(int((diffs > 0).sum()), len(diffs), 0.5, alternative="greater")
    return bool(test.pvalue <= 0.05)


def separation_low(
    round_: list[dict[str, np.ndarray]], rng: np.random.Generator, n_boot: int = 200
) -> float:
    """C1's interval's lower bound: seeds resampled within each arm and bracket (``n1`` once
    per draw, shared), the brackets kept (stratified), AUC averaged over brackets."""
    draws = []
    for _ in range(n_boot):
        n1 = rng.integers(0, 10, 10)
        found = []
        for b in round_:
            pos = b["p1-10"][0][rng.integers(0, 5, 5)]
            neg = np.concatenate([b["n1"][0][n1], b["n2-10"][0][rng.integers(0, 5, 5)]])
            found.append(auc(pos, neg))
        draws.append(np.mean(found))
    return float(np.percentile(draws, 2.5))


def power_table(
    effects: tuple[float, ...] = (0.52, 0.26), simulations: int = 200, seed: int = 0
) -> dict[str, dict[str, float]]:
    """The share of simulated rounds in which each criterion passes, per effect."""
    rng = np.random.default_rng(seed)
    table = {}
    for effect in effects:
        passes = [criteria(simulate(effect, Model(), rng), rng) for _ in range(simulations)]
        table[f"{effect:.2f}"] = {c: float(np.mean([p[c] for p in passes])) for c in passes[0]}
    return table


if __name__ == "__main__":
    import json

    print(json.dumps(power_table(), indent=1))
