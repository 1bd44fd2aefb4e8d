"""The four outcomes of :mod:`engine.verdict` and the sentence that states one."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from engine.verdict_power import smallest_p

if TYPE_CHECKING:
    from engine.verdict import MatchClasses, Verdict, VerdictInputs, VerdictOptions

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
