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

from engine.validation.round2_criteria import Round, criteria

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


def simulate(effect: float, model: Model, rng: np.random.Generator) -> Round:
    """One simulated round: per bracket, per arm, ``(3, seeds)``; ``n1``'s 10 seeds shared."""
    n1 = rng.normal(0, model.seed_sd, 10)
    return [_bracket(effect, arms, n1, model, rng) for arms in ON_BRACKET]


def _passes(round_: Round, rng: np.random.Generator) -> dict[str, bool]:
    """Whether each criterion passes on one simulated round (C1's bootstrap: 200 draws)."""
    return {c.name.split()[0]: bool(c.passed) for c in criteria(round_, rng, n_boot=200)}


def power_table(
    effects: tuple[float, ...] = (0.52, 0.26), simulations: int = 200, seed: int = 0
) -> dict[str, dict[str, float]]:
    """The share of simulated rounds in which each criterion passes, per effect."""
    rng = np.random.default_rng(seed)
    table = {}
    for effect in effects:
        passes = [_passes(simulate(effect, Model(), rng), rng) for _ in range(simulations)]
        table[f"{effect:.2f}"] = {c: float(np.mean([p[c] for p in passes])) for c in passes[0]}
    return table


if __name__ == "__main__":
    import json

    print(json.dumps(power_table(), indent=1))
