"""Power of each criterion at the planned seeds, by simulation (docs/validation.md §4.2).

A simulated validation draws each arm's CA per seed and bracket from a model with the
features the real one has: a shared base CA, a shift per arm, a between-seed spread, a
between-bracket spread and match noise, clipped to [0, 1]; and a ground truth U that moves
with the same shift plus its own seed noise. The shift is ``effect`` times the arm's share of
it (:data:`SHARES`: the dose response, none for the controls, a negative one for inverted
advice). The product's verdict is its core decision, the exact permutation test of per-seed
CA against ``n1`` at ``alpha`` (the "cannot tell" rules are left out: they only remove calls).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.validation import criteria
from engine.validation.criteria import ArmData, Table
from engine.validation.design import ARMS, BASELINE
from engine.verdict_power import permutation_p

#: Each arm's share of the effect at λ = 10.
SHARES = {
    "n1": 0.0,
    "n2-1": 0.0,
    "n2-10": 0.0,
    "n3": -0.5,
    "p1-1": 0.2,
    "p1-3": 0.5,
    "p1-10": 1.0,
    "bipars-em": 0.2,
    "bipars-mgl": 0.2,
}


@dataclass(frozen=True)
class Model:
    """The simulated CA and U: ``base`` CA of ``n1``; spreads of seeds, brackets and match
    noise (CA units); U moves by ``truth_gain`` per unit of CA shift, with ``truth_sd``."""

    base: float = 0.3
    seed_sd: float = 0.1
    bracket_sd: float = 0.05
    noise_sd: float = 0.05
    truth_gain: float = 1.0
    truth_sd: float = 0.05


def simulate(
    effect: float, seeds: int, brackets: int, model: Model, rng: np.random.Generator
) -> Table:
    """One simulated validation: every arm of :data:`ARMS` under one judge."""
    bracket_shift = rng.normal(0, model.bracket_sd, brackets)
    table = {}
    for arm in ARMS:
        shift = effect * SHARES[arm.name]
        seed_shift = rng.normal(0, model.seed_sd, (seeds, 1))
        noise = rng.normal(0, model.noise_sd, (seeds, brackets))
        ca = np.clip(model.base + shift + seed_shift + bracket_shift + noise, 0, 1)
        truth = model.truth_gain * (shift + seed_shift[:, 0]) + rng.normal(0, model.truth_sd, seeds)
        table[arm.name] = ArmData(ca, truth)
    return table


def decisions(table: Table, rng: np.random.Generator, alpha: float = 0.05) -> dict[str, str]:
    """Each arm's call against ``n1`` by the verdict's test: ``used``, ``against`` or
    ``no-different``."""
    base = table[BASELINE].run_ca
    calls = {}
    for name, data in table.items():
        p = float(permutation_p(data.run_ca, base, rng))
        diff = float(np.mean(data.run_ca) - np.mean(base))
        calls[name] = "no-different" if p >= alpha else ("used" if diff > 0 else "against")
    return calls


def placebo_calls(
    table: Table, rng: np.random.Generator, splits: int = 20, alpha: float = 0.05
) -> list[str]:
    """``n1``'s seeds split at random into halves, one judged against the other."""
    ca = table[BASELINE].run_ca
    calls = []
    for _ in range(splits):
        order = rng.permutation(len(ca))
        half = len(ca) // 2
        a, b = ca[order[:half]], ca[order[half:]]
        p = float(permutation_p(a, b, rng))
        calls.append(
            "no-different" if p >= alpha else ("used" if a.mean() > b.mean() else "against")
        )
    return calls


def passes(table: Table, rng: np.random.Generator, n_boot: int) -> dict[str, bool]:
    """Whether each criterion passes on one simulated validation."""
    calls = decisions(table, rng)
    found = [
        criteria.separation(table, rng, n_boot),
        criteria.dose_response(table, rng, n_boot),
        criteria.truth_agreement(table)[0],
        criteria.rejection(table, rng, n_boot),
        criteria.no_false_use(calls),
        criteria.placebo(placebo_calls(table, rng)),
        criteria.hard_cases(calls, table),
    ]
    return {c.name: bool(c.passed) for c in found}


def power(
    effect: float,
    *,
    seeds: int,
    brackets: int,
    rng: np.random.Generator,
    model: Model = Model(),
    simulations: int = 100,
    n_boot: int = 200,
) -> dict[str, float]:
    """The share of ``simulations`` simulated validations in which each criterion passes."""
    runs = [
        passes(simulate(effect, seeds, brackets, model, rng), rng, n_boot)
        for _ in range(simulations)
    ]
    return {name: float(np.mean([r[name] for r in runs])) for name in runs[0]}


#: The shifts in CA at λ = 10 simulated, and the designs: Hopper's 8 seeds, Humanoid's 5.
EFFECTS = (0.0, 0.1, 0.2, 0.3, 0.4)
DESIGNS = {"Hopper-v5": 8, "Humanoid-v5": 5}


def power_table(simulations: int = 200, seed: int = 0) -> dict[str, dict[str, dict[str, float]]]:
    """Power of every criterion per design and effect (docs/validation.md §4.2)."""
    rng = np.random.default_rng(seed)
    return {
        env: {
            f"{effect:.1f}": power(
                effect, seeds=seeds, brackets=5, rng=rng, simulations=simulations
            )
            for effect in EFFECTS
        }
        for env, seeds in DESIGNS.items()
    }


if __name__ == "__main__":
    import json
    from dataclasses import asdict

    print(json.dumps({"model": asdict(Model()), "power": power_table()}, indent=1))
