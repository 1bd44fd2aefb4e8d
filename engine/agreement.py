"""Label quality and agreement across labellers of pairwise choices (issue 14).

A label is a choice between two candidates; across labellers it is keyed by the unordered
pair ``(low id, high id)`` and its value is the winner. Pure functions of plain data.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy

Pair = tuple[int, int]
#: Each labeller's choices: labeller -> (unordered pair -> winner).
Choices = Mapping[int, Mapping[Pair, int]]


@dataclass(frozen=True)
class SideBias:
    """``left`` of ``labels`` choices went to the left picture; ``p_value`` is the two-sided
    exact binomial test of a fair side (``None`` without labels)."""

    labels: int
    left: int
    left_share: float | None
    p_value: float | None


def side_bias(*, left: int, labels: int) -> SideBias:
    """Position bias: the share of left choices and :func:`scipy.stats.binomtest` at 1/2."""
    if labels == 0:
        return SideBias(0, 0, None, None)
    return SideBias(
        labels,
        left,
        left / labels,
        float(scipy.stats.binomtest(left, labels, 0.5, alternative="two-sided").pvalue),
    )


def pair_key(a: int, b: int) -> Pair:
    return (a, b) if a < b else (b, a)


@dataclass(frozen=True)
class PairAgreement:
    """Labellers ``a`` and ``b`` decided ``shared`` pairs alike in ``agreement`` of them."""

    a: int
    b: int
    shared: int
    agreement: float | None


def pairwise_agreement(choices: Choices) -> list[PairAgreement]:
    """Agreement of every two labellers on the pairs both decided (ids in ascending order)."""
    out = []
    for a, b in itertools.combinations(sorted(choices), 2):
        shared = choices[a].keys() & choices[b].keys()
        same = sum(choices[a][k] == choices[b][k] for k in shared)
        out.append(PairAgreement(a, b, len(shared), same / len(shared) if shared else None))
    return out


def mean_agreement(pairs: list[PairAgreement]) -> float | None:
    """The mean over labeller pairs that share at least one pair."""
    values = [p.agreement for p in pairs if p.agreement is not None]
    return float(np.mean(values)) if values else None


def shared_units(choices: Choices) -> list[Pair]:
    """Pairs decided by at least two labellers (the units that agreement is measured on)."""
    counts: dict[Pair, int] = {}
    for decided in choices.values():
        for key in decided:
            counts[key] = counts.get(key, 0) + 1
    return sorted(k for k, n in counts.items() if n >= 2)


def alpha_nominal(choices: Choices) -> float | None:
    """Krippendorff's alpha (nominal) over the shared pairs. A unit's value is which of its
    two candidates won (0: the lower id, 1: the higher), so that every unit has the same two
    categories. ``None`` when no pair is
    shared or the shared pairs' values do not vary (alpha is undefined then)."""
    units = shared_units(choices)
    if not units:
        return None
    data = np.full((len(choices), len(units)), np.nan)
    for row, labeller in enumerate(sorted(choices)):
        for col, key in enumerate(units):
            if (winner := choices[labeller].get(key)) is not None:
                data[row, col] = float(winner == key[1])
    values = data[~np.isnan(data)]
    if np.all(values == values[0]):
        return None
    return _nominal_alpha(data)


def _nominal_alpha(data: np.ndarray) -> float | None:
    """Krippendorff's alpha, nominal, of ``data`` (labellers x units, NaN where missing),
    from the coincidence matrix (Krippendorff 2011, "Computing Krippendorff's alpha-
    reliability"). Written here, not taken from the ``krippendorff`` package, because that
    package is GPL-3.0-or-later and ACV is MIT; the tests check it by hand.
    """
    categories = np.unique(data[~np.isnan(data)])
    counts = np.stack([(data == c).sum(axis=0) for c in categories])  # (categories, units)
    pairable = counts.sum(axis=0)
    counts, pairable = counts[:, pairable >= 2], pairable[pairable >= 2]
    # o[c, k] = sum over units of n_uc (n_uk - [c == k]) / (m_u - 1)
    coincidences = np.einsum("cu,ku,u->ck", counts, counts, 1 / (pairable - 1))
    coincidences -= np.diag((counts / (pairable - 1)).sum(axis=1))
    n_c = coincidences.sum(axis=1)
    n = n_c.sum()
    observed = (n - np.trace(coincidences)) / n
    expected = (n * n - (n_c * n_c).sum()) / (n * (n - 1)) if n > 1 else 0.0
    # no variation among the pairable values: alpha is undefined
    return None if expected == 0 else float(1 - observed / expected)
