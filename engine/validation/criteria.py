"""The validation's criteria (docs/validation.md §4), written before any run.

All of them read one judge's :class:`ArmData` per arm: each run's CA on every evaluation
bracket and the ground truth U of each run. A run's CA is its mean over the brackets that have
contested matches; Δ of a run is its CA minus the mean CA of ``n1``; ΔU is its U minus the U of
``n1`` at the same seed index. Intervals are 95% percentile intervals of a hierarchical
bootstrap: brackets are drawn with replacement (the same draw for every arm), then seeds
within each arm. scipy's ``bootstrap`` resamples one level only, hence :func:`_resample`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy

from engine.validation.design import BASELINE
from engine.verdict_power import auc

N_BOOT = 2000
POSITIVE_TOP = "p1-10"
SHUFFLED = ("n2-1", "n2-10")
DOSES = {"n1": 0.0, "p1-1": 1.0, "p1-3": 3.0, "p1-10": 10.0}
HARD_CASES = ("p1-1", "bipars-em")
#: The bootstrapped criteria: their names, and the arms each one reads.
NEEDS = {
    "separation": ("AUC p1-10 vs n1+n2", (POSITIVE_TOP, *SHUFFLED)),
    "dose_response": ("rho(lambda, delta)", tuple(DOSES)),
    "rejection": ("delta(n3)", ("n3",)),
}


@dataclass(frozen=True)
class ArmData:
    """One arm under one judge.

    Attributes:
        ca: CA of each seed on each bracket, shape ``(seeds, brackets)``; NaN where the bracket
            has no contested match.
        truth: the teacher's own score U of each seed's agent, shape ``(seeds,)``.
    """

    ca: np.ndarray
    truth: np.ndarray

    @property
    def run_ca(self) -> np.ndarray:
        """Each seed's CA over the brackets, shape ``(seeds,)``."""
        return _nanmean(self.ca, axis=1)


Table = Mapping[str, ArmData]


def _nanmean(values: np.ndarray, axis: int | None = None) -> np.ndarray:
    """The mean over the finite values; NaN, without numpy's warning, where there are none."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.asarray(np.nanmean(values, axis=axis))


@dataclass(frozen=True)
class Criterion:
    """One criterion's measured value, its interval (when it has one) and whether it passed
    (None: it could not be computed, which is reported as not passed)."""

    name: str
    value: float | None
    low: float | None = None
    high: float | None = None
    passed: bool | None = None
    note: str = ""


def run_delta(table: Table, arm: str) -> np.ndarray:
    """Δ of each seed of ``arm``: its CA minus the mean CA of ``n1``, shape ``(seeds,)``."""
    return np.asarray(table[arm].run_ca - _nanmean(table[BASELINE].run_ca))


def delta_truth(table: Table, arm: str) -> np.ndarray:
    """ΔU of each seed of ``arm`` against ``n1`` at the same seed index."""
    k = min(len(table[arm].truth), len(table[BASELINE].truth))
    return np.asarray(table[arm].truth[:k] - table[BASELINE].truth[:k])


def known_direction(delta_u: np.ndarray, alpha: float = 0.05) -> str:
    """``follows``, ``rejects`` or ``unknown``: the one-sided exact sign-flip test of ΔU
    across seeds at ``alpha``, in each direction."""
    if len(delta_u) < 2 or not np.any(delta_u):
        return "unknown"
    for direction, alternative in (("follows", "greater"), ("rejects", "less")):
        p = scipy.stats.permutation_test(
            (delta_u,),
            np.mean,
            permutation_type="samples",
            alternative=alternative,
            n_resamples=np.inf,
        ).pvalue
        if p < alpha:
            return direction
    return "unknown"


def _resample(table: Table, rng: np.random.Generator) -> dict[str, ArmData]:
    n_brackets = next(iter(table.values())).ca.shape[1]
    brackets = rng.integers(0, n_brackets, n_brackets)
    drawn = {}
    for name, data in table.items():
        seeds = rng.integers(0, len(data.truth), len(data.truth))
        drawn[name] = ArmData(data.ca[np.ix_(seeds, brackets)], data.truth[seeds])
    return drawn


def _interval(
    table: Table, statistic: Callable[[Table], float], rng: np.random.Generator, n_boot: int
) -> tuple[float, float]:
    draws = np.array([statistic(_resample(table, rng)) for _ in range(n_boot)])
    draws = draws[np.isfinite(draws)]
    if not len(draws):
        return float("nan"), float("nan")
    return float(np.percentile(draws, 2.5)), float(np.percentile(draws, 97.5))


def _separation(table: Table) -> float:
    positive = table[POSITIVE_TOP].run_ca
    negative = np.concatenate([table[a].run_ca for a in (BASELINE, *SHUFFLED)])
    positive, negative = positive[np.isfinite(positive)], negative[np.isfinite(negative)]
    return auc(positive, negative) if len(positive) and len(negative) else float("nan")


def separation(table: Table, rng: np.random.Generator, n_boot: int = N_BOOT) -> Criterion:
    """AUC of CA between ``p1-10`` and ``n1`` ∪ ``n2``: passes at >= 0.9 with the interval's
    lower bound >= 0.75."""
    value = _separation(table)
    low, high = _interval(table, _separation, rng, n_boot)
    return _bounded("AUC p1-10 vs n1+n2", value, low, high, value >= 0.9 and low >= 0.75)


def _dose_rho(table: Table) -> float:
    doses = [(DOSES[a], d) for a in DOSES for d in run_delta(table, a) if np.isfinite(d)]
    if len({dose for dose, _ in doses}) < 2:
        return float("nan")
    return float(scipy.stats.spearmanr(*zip(*doses, strict=True)).statistic)


def dose_response(table: Table, rng: np.random.Generator, n_boot: int = N_BOOT) -> Criterion:
    """Spearman ρ(λ, Δ) over the runs of ``n1`` (λ = 0) and ``p1`` at λ = 1, 3, 10: passes
    when ρ > 0 and its interval excludes 0."""
    value = _dose_rho(table)
    low, high = _interval(table, _dose_rho, rng, n_boot)
    return _bounded("rho(lambda, delta)", value, low, high, value > 0 and low > 0)


def truth_agreement(table: Table) -> tuple[Criterion, dict[str, float]]:
    """Spearman ρ(Δ, ΔU) across every run but ``n1``'s (passes at >= 0.7), and within each arm
    (reported: pooled across arms it mostly measures the gap between λ = 10 and ``n1``)."""
    pairs = {
        arm: (run_delta(table, arm)[: len(delta_truth(table, arm))], delta_truth(table, arm))
        for arm in table
        if arm != BASELINE
    }
    within = {arm: _rho(d, u) for arm, (d, u) in pairs.items()}
    if not pairs:
        return _bounded("rho(delta, delta U)", float("nan"), None, None, False), within
    pooled = _rho(*(np.concatenate(side) for side in zip(*pairs.values(), strict=True)))
    return _bounded("rho(delta, delta U)", pooled, None, None, pooled >= 0.7), within


def _rho(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3 or np.ptp(x[ok]) == 0 or np.ptp(y[ok]) == 0:
        return float("nan")
    return float(scipy.stats.spearmanr(x[ok], y[ok]).statistic)


def _mean_delta(arm: str) -> Callable[[Table], float]:
    return lambda table: float(_nanmean(run_delta(table, arm)))


def rejection(table: Table, rng: np.random.Generator, n_boot: int = N_BOOT) -> Criterion:
    """Δ of ``n3`` (inverted advice): passes when it is below 0 with an interval below 0."""
    value = _mean_delta("n3")(table)
    low, high = _interval(table, _mean_delta("n3"), rng, n_boot)
    return _bounded("delta(n3)", value, low, high, value < 0 and high < 0)


def no_false_use(outcomes: Mapping[str, str]) -> Criterion:
    """The product's verdict never says ``used`` for shuffled advice at either scale."""
    said = [arm for arm in SHUFFLED if outcomes.get(arm) == "used"]
    missing = [arm for arm in SHUFFLED if arm not in outcomes]
    return Criterion(
        "no 'used' for n2",
        float(len(said)),
        passed=None if missing else not said,
        note=f"said 'used': {', '.join(said) or 'none'}",
    )


def placebo(outcomes: Sequence[str]) -> Criterion:
    """Over random splits of ``n1``'s seeds judged against each other, at most 10% say
    ``used`` or ``against``."""
    if not outcomes:
        return Criterion("placebo", None, note="no split judged")
    share = sum(o in ("used", "against") for o in outcomes) / len(outcomes)
    return Criterion("placebo", share, passed=share <= 0.10, note=f"{len(outcomes)} splits")


def hard_cases(outcomes: Mapping[str, str], table: Table) -> Criterion:
    """Whenever the exact test on ΔU says a hard-case arm (``p1-1``, ``bipars-em``) follows
    the advice, the verdict says ``used``. Vacuous (reported, passed) when none follows; not
    computed when either arm is not trained."""
    missing = [a for a in HARD_CASES if a not in table]
    if missing:
        return Criterion("hard cases", None, note=f"arms not trained: {', '.join(missing)}")
    follows = [a for a in HARD_CASES if known_direction(delta_truth(table, a)) == "follows"]
    missed = [a for a in follows if outcomes.get(a) != "used"]
    note = f"known to follow: {', '.join(follows) or 'none (vacuous)'}"
    return Criterion("hard cases", float(len(follows) - len(missed)), passed=not missed, note=note)


def _bounded(
    name: str, value: float, low: float | None, high: float | None, passed: bool
) -> Criterion:
    if not np.isfinite(value):
        return Criterion(name, None, note="too few runs or contested matches to compute")
    return Criterion(name, value, low, high, bool(passed))
