"""The reproduction's rule: a claim holds only against a baseline, with an interval that
excludes it (``app.reproduce.predictions``), on hand-written arms."""

from __future__ import annotations

from typing import Any

import pytest
from scipy import stats

from app.reproduce.intervals import difference, seed_statistics
from app.reproduce.predictions import predictions


def _arm(returns: list[float], title: str) -> dict[str, Any]:
    """An arm whose seeds have ``returns``; its judges keep every match, none of them bent."""
    judged = {"match_agreement": 1.0, "contested_agreement": 1.0, "bent_share": 0.0}
    point = {"step": 1000, "judges": {j: judged for j in ("shaped", "behaviour")}}
    seeds = [
        {"seed": i, "final_return_100": r, "main": [point], "agent": [point]}
        for i, r in enumerate(returns)
    ]
    final = {
        j: {k: seed_statistics([v] * len(returns)) for k, v in judged.items()}
        | {"contested_kept": ["1/1"] * len(returns)}
        for j in ("shaped", "behaviour")
    }
    return {
        "title": title,
        "seeds": seeds,
        "final_return": seed_statistics(returns),
        "final": {"main": final, "agent": final},
    }


def _control_claim(case2: list[float], control: list[float]) -> dict[str, Any]:
    arms = {"case2": _arm(case2, "Case 2"), "control": _arm(control, "Control")}
    return next(c for c in predictions(arms) if c["claim"].startswith("Control"))


@pytest.mark.parametrize(
    ("case2", "control", "holds"),
    [
        ([600.0, 610.0, 620.0], [500.0, 505.0, 510.0], True),  # well apart
        ([600.0, 700.0, 800.0], [450.0, 700.0, 720.0], False),  # a higher mean is not enough
        ([600.0], [500.0], False),  # one seed: no interval, never holds
        ([600.0, 600.0], [500.0, 500.0], True),  # constant sides: the difference is exact
    ],
)
def test_a_claim_holds_only_when_the_interval_excludes_the_baseline(
    case2: list[float], control: list[float], holds: bool
) -> None:
    claim = _control_claim(case2, control)
    assert claim["holds"] is holds
    assert "interval of the difference above 0" in claim["rule"]


def test_the_difference_is_welchs_interval() -> None:
    a, b = [1.0, 2.0, 4.0], [0.0, 0.5, 0.7, 0.2]
    expected = stats.ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    got = difference(a, b)
    assert got["delta"] == pytest.approx(7 / 3 - 0.35)
    assert (got["ci_low"], got["ci_high"]) == pytest.approx(tuple(expected))


def test_seeds_without_a_value_are_left_out() -> None:
    assert difference([None, 1.0], [0.0, 0.0])["ci_low"] is None
    assert difference([None], [0.0])["delta"] is None
