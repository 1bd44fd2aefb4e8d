"""The whole-bracket verdict: do the advised agents line up with the person's *whole* tree
more than agents trained without the advice? (issue 40; declared as validation round 2's
primary in docs/validation.md §6, before any of its runs.)

1. **Alignment per run.** ``r`` = Pearson's correlation, over the bracket's ``N``
   candidates, between the run's judge score of each candidate and the person's tree reward
   T_r there (:func:`tree_values`: the tree alone, never a judge's recorded scores). A run
   whose scores are constant over the bracket has no preference: ``r = 0``.
2. **Δ** = mean ``r`` of the advised seeds minus mean ``r`` of the matched no-advice
   baseline's seeds. The exact two-sided permutation test of the per-seed ``r`` decides at
   ``alpha``; a bootstrap of seeds within each arm gives the interval, and the AUC is
   reported beside it.
3. **One outcome word.** Only the declared primary at the runs' last planned checkpoint
   (``stage="primary"``) says "used", "went against", "no different" or "cannot tell";
   an ``interim`` checkpoint or a ``diagnostic`` (another judge, another scoring) shows Δ and
   its interval only, so that the many looks a page offers cannot each say "used".

Contested matches (:mod:`engine.verdict`) stay as the explanation of *which* advice was kept;
they no longer decide. :func:`engine.verdict_specificity.specificity` asks whether a run
follows *this* tree more than random trees over the same bracket, and never decides.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import scipy

from engine.errors import InputError
from engine.treefile import TreeDocument
from engine.verdict_outcome import LABELS
from engine.verdict_power import (
    auc,
    mean_difference,
    min_detectable_shift,
    permutation_p,
    smallest_p,
)

Stage = Literal["primary", "interim", "diagnostic"]


@dataclass(frozen=True)
class AlignmentOptions:
    """The whole-bracket verdict's settings (docs/validation.md §6.2 says why).

    Attributes:
        alpha: the permutation test's two-sided level.
        power: the power at which the smallest detectable Δ is computed.
        seed_sd: the between-seed spread of ``r`` assumed by the smallest detectable Δ:
            round 1's ``n1`` seeds under ``behaviour`` on Humanoid-v5 (0.196, rounded up).
        min_candidates: fewer candidates than this is "cannot tell" (a rule of thumb, §6.2).
        min_seeds: fewer seeds than this in either arm is "cannot tell".
        n_boot: bootstrap draws of the interval.
    """

    alpha: float = 0.05
    power: float = 0.8
    seed_sd: float = 0.2
    min_candidates: int = 8
    min_seeds: int = 4
    n_boot: int = 2000


@dataclass(frozen=True)
class AlignmentVerdict:
    """The whole-bracket verdict and what it rests on.

    Attributes:
        stage: ``primary``, ``interim`` or ``diagnostic`` (module docstring, step 3).
        outcome: ``used``, ``against``, ``no-different`` or ``cannot-tell`` for the primary;
            None for an interim look or a diagnostic (they carry no outcome word).
        label: the outcome in words, or the stage's name.
        reason: why "cannot tell" (None otherwise).
        r_advised: each advised seed's alignment ``r``, shape ``(k_a,)``.
        r_baseline: each baseline seed's ``r``, shape ``(k_b,)``.
        delta: mean ``r`` advised minus baseline (None when an arm is empty).
        interval: 95% crossed-bootstrap interval of ``delta``.
        p_value: the exact two-sided permutation test's p.
        auc: P(an advised seed's ``r`` > a baseline seed's), ties counted half.
        min_detectable_delta: the smallest Δ detected at ``alpha`` with ``power``.
        alpha: the test's level.
        power: the power of ``min_detectable_delta``.
        text: the one-sentence verdict.
    """

    stage: Stage
    outcome: str | None
    label: str
    reason: str | None
    r_advised: tuple[float, ...]
    r_baseline: tuple[float, ...]
    delta: float | None
    interval: tuple[float, float] | None
    p_value: float | None
    auc: float | None
    min_detectable_delta: float | None
    alpha: float
    power: float
    text: str = ""

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data (tuples as lists)."""
        out = asdict(self)
        out["r_advised"], out["r_baseline"] = list(self.r_advised), list(self.r_baseline)
        out["interval"] = None if self.interval is None else list(self.interval)
        return out


def tree_values(doc: TreeDocument) -> np.ndarray:
    """T_r of each candidate by the tree alone, shape ``(N,)``, candidates in id order: what
    a person's tree holds (a simulated teacher's hidden scores are never read)."""
    return np.array([doc.tree.nodes[c.id].reward for c in doc.candidates], dtype=np.float64)


def alignment(scores: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Pearson's ``r`` of each row of ``scores`` with ``values`` along the last axis.

    Args:
        scores: judge scores, shape ``(..., N)``.
        values: the tree's values, shape ``(..., N)`` (broadcast against ``scores``).

    Returns:
        shape ``(...)``; 0 where either side is constant (no preference, nothing to line up).
    """
    x = scores - scores.mean(axis=-1, keepdims=True)
    y = values - values.mean(axis=-1, keepdims=True)
    norm = np.sqrt((x * x).sum(axis=-1) * (y * y).sum(axis=-1))
    # a spread below float noise is a constant: 1e-12 of the scale, not an exact zero
    flat = norm <= 1e-12 * (np.abs(scores).max(axis=-1) + 1) * (np.abs(values).max(axis=-1) + 1)
    out: np.ndarray = np.where(flat, 0.0, (x * y).sum(axis=-1) / np.where(flat, 1.0, norm))
    return out


def seed_interval(
    r_advised: np.ndarray, r_baseline: np.ndarray, rng: np.random.Generator, n_boot: int = 2000
) -> tuple[float, float]:
    """95% percentile interval of Δ, resampling seeds within each arm. The candidates stay
    fixed: the verdict is about the person's own bracket, as the permutation test is."""
    found = scipy.stats.bootstrap(
        (r_advised, r_baseline),
        mean_difference,
        n_resamples=n_boot,
        method="percentile",
        vectorized=True,
        rng=rng,
    )
    return float(found.confidence_interval.low), float(found.confidence_interval.high)


def alignment_verdict(
    values: np.ndarray,
    advised: np.ndarray,
    baseline: np.ndarray,
    rng: np.random.Generator,
    options: AlignmentOptions = AlignmentOptions(),
    stage: Stage = "primary",
) -> AlignmentVerdict:
    """The whole-bracket verdict of the advised runs against the baseline (module doc).

    Args:
        values: the person's T_r per candidate, shape ``(N,)`` (:func:`tree_values`).
        advised: the judge's scores on the advised runs, shape ``(k_a, N)``.
        baseline: the same judge on the matched no-advice runs, shape ``(k_b, N)``.
        rng: draws the bootstrap.
        options: level, power, spread and the "cannot tell" floors.
        stage: ``primary`` gets an outcome word; ``interim`` and ``diagnostic`` do not.
    """
    _check_shapes(values, advised, baseline)
    r_a, r_b = alignment(advised, values), alignment(baseline, values)
    mde = min_detectable_shift(
        len(r_a), len(r_b), alpha=options.alpha, power=options.power, seed_sd=options.seed_sd
    )
    stats = _statistics(r_a, r_b, rng, options)
    reason = cannot_tell_reason(values, advised, baseline, mde, options)
    outcome, label, reason = _outcome(stage, reason, stats, options.alpha)
    found = AlignmentVerdict(
        stage,
        outcome,
        label,
        reason,
        tuple(r_a.tolist()),
        tuple(r_b.tolist()),
        min_detectable_delta=mde,
        alpha=options.alpha,
        power=options.power,
        **stats,
    )
    return AlignmentVerdict(**{**found.__dict__, "text": sentence(found)})


def _outcome(
    stage: Stage, reason: str | None, stats: dict[str, Any], alpha: float
) -> tuple[str | None, str, str | None]:
    """``(outcome, label, reason)``: no outcome word but for the primary; then "cannot tell"
    with its reason, else the test decides and Δ's sign names it."""
    if stage != "primary":
        return None, stage, reason
    if reason is not None or stats["p_value"] is None:
        return "cannot-tell", LABELS["cannot-tell"], reason or "no test"
    if stats["p_value"] <= alpha and stats["delta"] != 0:
        outcome = "used" if stats["delta"] > 0 else "against"
    else:
        outcome = "no-different"
    return outcome, LABELS[outcome], None


def _check_shapes(values: np.ndarray, advised: np.ndarray, baseline: np.ndarray) -> None:
    if np.ndim(values) != 1 or len(values) < 2:
        raise InputError("the tree's values must be a flat array over at least 2 candidates")
    for name, arm in (("advised", advised), ("baseline", baseline)):
        if np.ndim(arm) != 2 or np.shape(arm)[1] != len(values):
            raise InputError(f"{name} scores must have shape (seeds, {len(values)})")
        if not np.isfinite(arm).all():
            raise InputError(f"{name} scores must be finite")


def _statistics(
    r_a: np.ndarray,
    r_b: np.ndarray,
    rng: np.random.Generator,
    options: AlignmentOptions,
) -> dict[str, Any]:
    """Δ, interval, p and AUC; None where an arm has fewer than 2 seeds (no test, and no
    spread to resample)."""
    if min(len(r_a), len(r_b)) < 2:
        return {"delta": None, "interval": None, "p_value": None, "auc": None}
    return {
        "delta": float(r_a.mean() - r_b.mean()),
        "interval": seed_interval(r_a, r_b, rng, options.n_boot),
        "p_value": float(permutation_p(r_a, r_b, rng)),
        "auc": auc(r_a, r_b),
    }


def cannot_tell_reason(
    values: np.ndarray,
    advised: np.ndarray,
    baseline: np.ndarray,
    mde: float | None,
    options: AlignmentOptions,
) -> str | None:
    """Why the design cannot reach a verdict, or None when it can (checked in this order)."""
    k_a, k_b, n = len(advised), len(baseline), len(values)
    if min(k_a, k_b) < options.min_seeds:
        return (
            f"{k_a} advised and {k_b} baseline seeds: at least {options.min_seeds} per arm "
            f"needed (the exact test's floor here is p = {smallest_p(k_a, k_b):.2g})"
        )
    if n < options.min_candidates:
        return f"only {n} candidates in the bracket, at least {options.min_candidates} needed"
    if not alignment(values[None], values).any():
        return "the tree values every candidate alike: it states no preference"
    runs = np.concatenate([advised, baseline])
    if not alignment(runs, values).any():
        return "the judge scores every candidate alike on every run"
    if mde is None:
        return f"this design cannot detect even the largest Δ with power {options.power:g}"
    return None


def sentence(v: AlignmentVerdict) -> str:
    """The one-sentence verdict, then the smallest Δ the design detects."""
    k_a, k_b = len(v.r_advised), len(v.r_baseline)
    head = "Over the whole bracket"
    if v.delta is None or v.interval is None:
        return f"{head}: {v.label} ({v.reason})."
    p = "no test" if v.p_value is None else f"p = {v.p_value:.3f}"
    mean_a, mean_b = np.mean(v.r_advised), np.mean(v.r_baseline)
    body = (
        f"{head}, your agents line up with your tree at r = {mean_a:.2f} ({k_a} seeds); "
        f"agents without your advice at r = {mean_b:.2f} ({k_b} seeds). "
        f"Δ = {v.delta:.2f} [{v.interval[0]:.2f}, {v.interval[1]:.2f}], {p}"
    )
    said = f"{v.label}" + (f" ({v.reason})" if v.reason else "")
    if v.outcome is None:
        said = f"{v.stage}, no verdict"
    mde = v.min_detectable_delta
    can = "cannot detect any Δ" if mde is None else f"detects Δ ≥ {mde:.2f}"
    return f"{body}: {said}. This design {can} at α = {v.alpha:g} with power {v.power:g}."
