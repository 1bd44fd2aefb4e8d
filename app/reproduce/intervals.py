"""Numbers over seeds as the reproduction reports them: a mean with Student's t 95% interval,
a difference of two arms' means with Welch's t 95% interval, and their text."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import stats


def seed_statistics(
    values: list[float | None], bounds: tuple[float, float] | None = None
) -> dict[str, float | int | None]:
    """Mean over seeds with a 95% Student's t interval (None for fewer than 2 seeds).

    Args:
        values: one number per seed; None (undefined at that seed) is left out.
        bounds: where the quantity must lie (a proportion: ``(0, 1)``); the interval is
            clipped to it.
    """
    x = np.asarray([v for v in values if v is not None], dtype=np.float64)
    if len(x) == 0:
        return {"n": 0, "mean": None, "ci_low": None, "ci_high": None}
    if len(x) < 2:
        return {"n": 1, "mean": float(x[0]), "ci_low": None, "ci_high": None}
    sem = stats.sem(x)
    low, high = (
        (x.mean(), x.mean())
        if sem == 0
        else stats.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=sem)
    )
    if bounds is not None:
        low, high = max(low, bounds[0]), min(high, bounds[1])
    return {"n": len(x), "mean": float(x.mean()), "ci_low": float(low), "ci_high": float(high)}


def difference(a: Sequence[float | None], b: Sequence[float | None]) -> dict[str, Any]:
    """Mean of ``a`` minus mean of ``b`` with Welch's t 95% interval (None with fewer than
    two values on either side). Values that are all equal on both sides give the point."""
    x, y = (np.asarray([v for v in vs if v is not None], dtype=np.float64) for vs in (a, b))
    delta = float(x.mean() - y.mean()) if len(x) and len(y) else None
    if len(x) < 2 or len(y) < 2:
        return {"delta": delta, "ci_low": None, "ci_high": None}
    if np.ptp(x) == 0 and np.ptp(y) == 0:  # scipy answers nan; the difference is exact
        return {"delta": delta, "ci_low": delta, "ci_high": delta}
    with warnings.catch_warnings():  # a constant side (PPO at 100% on every seed) is exact:
        warnings.simplefilter("ignore", RuntimeWarning)  # scipy warns of precision loss there
        low, high = stats.ttest_ind(x, y, equal_var=False).confidence_interval(0.95)
    return {"delta": delta, "ci_low": float(low), "ci_high": float(high)}


def diff_text(diff: dict[str, Any]) -> str:
    """``+0.14 [-0.05, 0.33]``, or ``n/a`` / no interval with too few seeds."""
    if diff["delta"] is None:
        return "n/a"
    f = (lambda v: f"{v:+.2f}") if abs(diff["delta"]) < 10 else (lambda v: f"{v:+.0f}")
    if diff["ci_low"] is None:
        return f"{f(diff['delta'])} (no interval: one seed)"
    return f"{f(diff['delta'])} [{f(diff['ci_low'])}, {f(diff['ci_high'])}]"


def stat_text(stat: dict[str, Any], pct: bool = False) -> str:
    """``0.62 [0.51, 0.73] (3 seeds)``; percentages with ``pct``."""
    if stat["mean"] is None:
        return "n/a"
    f = (
        (lambda v: f"{100 * v:.0f}%")
        if pct
        else (lambda v: f"{v:.2f}" if abs(v) < 10 else f"{v:.0f}")
    )
    ci = "" if stat["ci_low"] is None else f" [{f(stat['ci_low'])}, {f(stat['ci_high'])}]"
    return f"{f(stat['mean'])}{ci} ({stat['n']} seed{'s' * (stat['n'] != 1)})"
