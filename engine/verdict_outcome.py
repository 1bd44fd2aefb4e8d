"""The verdict's decision over the matches :mod:`engine.verdict` splits (its steps 3-4):
each run's share of contested matches kept, the test, one of four outcomes and the sentence
that states it."""

from __future__ import annotations

from typing import Any

import numpy as np

from engine.verdict import (
    MatchClasses,
    Pair,
    Verdict,
    VerdictInputs,
    VerdictOptions,
    classify,
    kept,
)
from engine.verdict_power import (
    auc,
    crossed_bootstrap,
    min_detectable_delta,
    permutation_p,
    smallest_p,
)

#: outcome -> its words in the verdict.
LABELS: dict[str, str] = {
    "used": "used your advice",
    "against": "went against your advice",
    "no-different": "no different from an agent without it",
    "cannot-tell": "cannot tell",
}


def outcome_and_reason(
    inputs: VerdictInputs,
    classes: MatchClasses,
    mde: float | None,
    delta: float | None,
    p_value: float | None,
    options: VerdictOptions,
) -> tuple[str, str, str | None]:
    """``(outcome, label, reason)``: "cannot tell" with its reason whenever the design could
    never reject (or the judge never chose), else the test decides and Δ's sign names it."""
    reason = cannot_tell_reason(inputs, classes, mde, options)
    if reason is not None or delta is None or p_value is None:
        return "cannot-tell", LABELS["cannot-tell"], reason or "no contested match to compare"
    if p_value <= options.alpha and delta != 0:
        outcome = "used" if delta > 0 else "against"
    else:
        outcome = "no-different"
    return outcome, LABELS[outcome], None


def cannot_tell_reason(
    inputs: VerdictInputs, classes: MatchClasses, mde: float | None, options: VerdictOptions
) -> str | None:
    """Why the design cannot reach a verdict, or None when it can (checked in this order)."""
    n, k_a, k_b = len(classes.contested), len(inputs.advised), len(inputs.baseline)
    if not len(inputs.pilot):
        return "no pilot baseline runs to pick the contested matches"
    if not k_a or not k_b:
        return "no advised runs" if not k_a else "no baseline runs"
    if n < options.min_contested:
        return (
            f"only {n} informative contested match{'es' * (n != 1)}, at least "
            f"{options.min_contested} needed; {len(classes.uninformative)} uninformative "
            "not counted"
        )
    floor = smallest_p(k_a, k_b)
    if floor > options.alpha:
        return (
            f"with {k_a} seed{'s' * (k_a != 1)} against {k_b}, the exact test never goes below "
            f"p = {floor:.2g}"
        )
    if mde is None:
        return f"this design cannot detect even Δ = 1 with power {options.power:g}"
    pairs = np.array(classes.contested, dtype=np.intp)  # (n, 3): a, b, winner
    runs = np.concatenate([inputs.advised, inputs.baseline])
    if (runs[:, pairs[:, 0]] == runs[:, pairs[:, 1]]).all():
        return "the judge ties every contested match on every run"
    return None


def sentence(v: Verdict) -> str:
    """The one-sentence verdict, then the smallest Δ the design detects."""
    n = len(v.matches.contested)
    where = f"On {n} match{'es' * (n != 1)} where your advice and an agent without it disagree"
    if v.delta is None or v.interval is None:
        head = f"{where}: {v.label} ({v.reason})."
    else:
        k_a, k_b = len(v.ca_advised), len(v.ca_baseline)
        kept_a, kept_b = n * sum(v.ca_advised) / k_a, n * sum(v.ca_baseline) / k_b
        p = (
            "no test"
            if v.p_value is None
            else f"p = {v.p_value:.3f}"
            if v.p_value >= 0.001
            else "p < 0.001"
        )
        low, high = v.interval
        why = f" ({v.reason})" if v.reason else ""
        head = (
            f"{where}, your agents kept {kept_a:.1f} ({k_a} seed{'s' * (k_a != 1)}); agents "
            f"without your advice kept {kept_b:.1f} ({k_b} seed{'s' * (k_b != 1)}). "
            f"Δ = {v.delta:.2f} [{low:.2f}, {high:.2f}], {p}: {v.label}{why}."
        )
    mde = v.min_detectable_delta
    can = "cannot detect any Δ" if mde is None else f"detects Δ ≥ {mde:.2f}"
    return f"{head} This design {can} at α = {v.alpha:g} with power {v.power:g}."


def _statistics(
    inputs: VerdictInputs,
    contested: tuple[Pair, ...],
    rng: np.random.Generator,
    options: VerdictOptions,
) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """Δ, its crossed bootstrap interval, the permutation test's p and the AUC (None where
    an arm or the matches are empty), and each arm's per-seed CA, shape ``(k,)``."""
    k_a, k_b = len(inputs.advised), len(inputs.baseline)
    if not (contested and k_a and k_b):
        empty: dict[str, Any] = {"delta": None, "interval": None, "p_value": None, "auc": None}
        return empty, np.zeros(0), np.zeros(0)
    kept_a, kept_b = kept(inputs.advised, contested), kept(inputs.baseline, contested)
    ca_a, ca_b = kept_a.mean(axis=1), kept_b.mean(axis=1)
    stats = {
        "delta": float(ca_a.mean() - ca_b.mean()),
        "interval": crossed_bootstrap(kept_a, kept_b, rng, options.n_boot),
        # scipy needs two seeds per arm; with one, no test could reach alpha anyway
        "p_value": float(permutation_p(ca_a, ca_b, rng)) if min(k_a, k_b) > 1 else None,
        "auc": auc(ca_a, ca_b),
    }
    return stats, ca_a, ca_b


def verdict(
    inputs: VerdictInputs, rng: np.random.Generator, options: VerdictOptions = VerdictOptions()
) -> Verdict:
    """Decide whether the advised runs kept the advice more than the baseline (module doc).

    Args:
        inputs: the advice, the three arms' judge scores and the matches.
        rng: draws the bootstrap (and a Monte Carlo test's relabellings at many seeds).
        options: margins, minimum matches, level and power.
    """
    classes = classify(inputs, options)
    sizes = len(classes.contested), len(inputs.advised), len(inputs.baseline)
    mde = min_detectable_delta(
        *sizes, alpha=options.alpha, power=options.power, seed_sd=options.seed_sd
    )
    stats, ca_a, ca_b = _statistics(inputs, classes.contested, rng, options)
    outcome, label, reason = outcome_and_reason(
        inputs, classes, mde, stats["delta"], stats["p_value"], options
    )
    result = Verdict(
        outcome,
        label,
        reason,
        classes,
        tuple(ca_a.tolist()),
        tuple(ca_b.tolist()),
        min_detectable_delta=mde,
        alpha=options.alpha,
        power=options.power,
        **stats,
    )
    return Verdict(**{**result.__dict__, "text": sentence(result)})
