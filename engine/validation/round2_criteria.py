"""Round 2's criteria (docs/validation.md §6.4), computed per advice bracket and averaged over
brackets. One home for the real analysis (:mod:`engine.validation.round2_analysis`) and the
power simulation (:mod:`engine.validation.power_round2`).

A round is a list of brackets; each maps an arm to its runs' ``(3, seeds)`` array: row 0 the
primary's ``r`` with the bracket's advice, row 1 ``r`` with the bracket's shuffled tree, row 2
the ground truth U. ``n1``'s 10 seeds are on every bracket; the product's verdict reads its
first 5 (100-104), matched with the arm's.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.stats import binomtest, spearmanr

from engine.validation.criteria import Criterion
from engine.validation.round2 import known_direction
from engine.verdict_power import auc, auc_rows, permutation_p

Bracket = dict[str, np.ndarray]
Round = list[Bracket]
#: The product's verdict of an arm's runs against ``n1``'s: ``used``, ``against``, ...
Call = Callable[[np.ndarray, np.ndarray], str]
N_BOOT = 2000


def verdict_call(rng: np.random.Generator, alpha: float = 0.05) -> Call:
    """The verdict's decision (:mod:`engine.verdict_bracket`): the exact two-sided
    permutation test of the arm's ``r`` against ``n1``'s first 5 seeds at ``alpha``."""

    def call(arm: np.ndarray, n1: np.ndarray) -> str:
        p = float(permutation_p(arm[0], n1[0, :5], rng))
        delta = arm[0].mean() - n1[0, :5].mean()
        return "no-different" if p > alpha else ("used" if delta > 0 else "against")

    return call


def separation(round_: Round, rng: np.random.Generator, n_boot: int = N_BOOT) -> Criterion:
    """C1: AUC of ``r``, ``p1-10`` against ``n1`` ∪ the bracket's ``n2-10``, averaged over
    brackets: passes at >= 0.9 with the stratified bootstrap's lower bound >= 0.75 (seeds
    drawn within each arm and bracket; ``n1``'s once per draw, shared by the brackets)."""
    value = float(np.mean([auc(b["p1-10"][0], _negatives(b, None, None)) for b in round_]))
    k = round_[0]["n1"].shape[1]
    n1 = rng.integers(0, k, size=(n_boot, k))
    draws = np.zeros(n_boot)
    for b in round_:
        positives = b["p1-10"][0][
            rng.integers(0, b["p1-10"].shape[1], size=(n_boot, b["p1-10"].shape[1]))
        ]
        shuffled = rng.integers(0, b["n2-10"].shape[1], size=(n_boot, b["n2-10"].shape[1]))
        draws += auc_rows(positives, _negatives(b, n1, shuffled)) / len(round_)
    low, high = np.percentile(draws, [2.5, 97.5])
    passed = value >= 0.9 and low >= 0.75
    return Criterion("C1 AUC p1-10 vs n1+n2-10", value, float(low), float(high), bool(passed))


def _negatives(b: Bracket, n1: np.ndarray | None, shuffled: np.ndarray | None) -> np.ndarray:
    """``n1``'s and the shuffled arm's ``r``, as drawn (indices ``(n_boot, k)``) or all."""
    if n1 is None or shuffled is None:
        return np.concatenate([b["n1"][0], b["n2-10"][0]])
    return np.concatenate([b["n1"][0][n1], b["n2-10"][0][shuffled]], axis=1)


def truth_agreement(round_: Round) -> Criterion:
    """C3: Spearman ρ(Δ, ΔU) over each bracket's runs but ``n1``'s, averaged: >= 0.7."""
    rhos = []
    for b in round_:
        runs = [b[a] for a in b if a != "n1"]
        delta = np.concatenate([r[0] - b["n1"][0].mean() for r in runs])
        delta_u = np.concatenate([r[2] - b["n1"][2].mean() for r in runs])
        rhos.append(float(spearmanr(delta, delta_u).statistic))
    value = float(np.mean(rhos))
    note = "per bracket " + ", ".join(f"{r:.2f}" for r in rhos)
    return Criterion("C3 rho(delta, delta U)", value, passed=bool(value >= 0.7), note=note)


def no_false_use(round_: Round, call: Call, alpha: float = 0.05) -> Criterion:
    """C5: the verdict never says ``used`` for a bracket's ``n2-10``, and says ``against`` no
    more often than its level allows (one-sided binomial test of the count at ``alpha``)."""
    calls = [call(b["n2-10"], b["n1"]) for b in round_]
    against = sum(c == "against" for c in calls)
    p = binomtest(against, len(calls), alpha, alternative="greater").pvalue
    passed = "used" not in calls and p > alpha
    return Criterion(
        "C5 shuffled never used",
        float(calls.count("used")),
        passed=bool(passed),
        note=", ".join(calls),
    )


def hard_case(round_: Round, call: Call) -> Criterion:
    """C7: ``bipars-em`` is called ``used`` on every bracket where U knows it follows."""
    known = [
        b
        for b in round_
        if "bipars-em" in b and known_direction(b["bipars-em"][2], b["n1"][2]) == "follows"
    ]
    calls = [call(b["bipars-em"], b["n1"]) for b in known]
    note = f"known to follow on {len(known)} bracket(s); called {', '.join(calls) or 'none'}"
    return Criterion(
        "C7 bipars-em",
        float(calls.count("used")),
        passed=all(c == "used" for c in calls),
        note=note,
    )


def specificity(round_: Round, alpha: float = 0.05) -> Criterion:
    """C8: every advised run lines up more with its own tree than with the bracket's shuffled
    tree, and every shuffled run the reverse: a one-sided exact sign test per arm."""
    ps = {arm: _sign_p(round_, arm, side) for arm, side in (("p1-10", 1), ("n2-10", -1))}
    note = ", ".join(f"{arm} p = {p:.3g}" for arm, p in ps.items())
    return Criterion(
        "C8 specificity", max(ps.values()), passed=max(ps.values()) <= alpha, note=note
    )


def _sign_p(round_: Round, arm: str, side: int) -> float:
    diffs = np.concatenate([side * (b[arm][0] - b[arm][1]) for b in round_])
    return float(binomtest(int((diffs > 0).sum()), len(diffs), 0.5, alternative="greater").pvalue)


def rejection(round_: Round, call: Call) -> Criterion:
    """C4, reported: the verdict says ``against`` for ``n3`` (bracket 0)."""
    said = call(round_[0]["n3"], round_[0]["n1"])
    return Criterion("C4 n3 went against (reported)", None, passed=said == "against", note=said)


def criteria(round_: Round, rng: np.random.Generator, n_boot: int = N_BOOT) -> list[Criterion]:
    """Every criterion of §6.4 (C4 only where ``n3`` is trained)."""
    call = verdict_call(rng)
    found = [
        separation(round_, rng, n_boot),
        truth_agreement(round_),
        no_false_use(round_, call),
        hard_case(round_, call),
        specificity(round_),
    ]
    return found + ([rejection(round_, call)] if "n3" in round_[0] else [])
