"""The pre-registered analysis (docs/validation.md §4) over the runs' measures: per judge, each
run's CA on every bracket, the product's verdict of each arm, the placebo, and every
criterion; ``summary.json`` is what the report and the docs are built from."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict
from typing import Any

import numpy as np

from engine.treefile import TreeDocument
from engine.validation import criteria
from engine.validation.criteria import ArmData, Criterion, Table
from engine.validation.design import BASELINE, PILOT, Plan
from engine.verdict import VerdictInputs, advice_scores, bracket_pairs, classify, kept
from engine.verdict_outcome import verdict

#: Random splits of ``n1``'s seeds judged against each other (the placebo).
PLACEBO_SPLITS = 20
Measures = Mapping[tuple[str, int], Mapping[str, Any]]


def _scores(measures: Measures, arm: str, seeds: list[int], judge: str, b: int) -> np.ndarray:
    return np.array([measures[(arm, s)]["scores"][judge][b] for s in seeds])


def _inputs(
    measures: Measures, plan: Plan, judge: str, bracket: TreeDocument, b: int, arm: str
) -> VerdictInputs:
    pilots, seeds = plan.pilot_seed_list(), list(range(plan.seeds))
    reward = np.mean([measures[(PILOT.name, s)]["reward"][b] for s in pilots], axis=0)
    return VerdictInputs(
        advice_scores(bracket),
        _scores(measures, arm, seeds, judge, b),
        _scores(measures, BASELINE, seeds, judge, b),
        _scores(measures, PILOT.name, pilots, judge, b),
        bracket_pairs(bracket),
        reward,
    )


def arm_table(
    measures: Measures,
    plan: Plan,
    judge: str,
    brackets: list[TreeDocument],
    *,
    every_match: bool = False,
) -> dict[str, ArmData]:
    """Each arm's CA per seed and bracket (NaN where the bracket has no contested match);
    with ``every_match``, the share of all the bracket's matches kept instead (the plain
    match agreement, which no baseline corrects)."""
    table = {}
    for arm in plan.chosen:
        ca = np.full((plan.seeds, len(brackets)), np.nan)
        for b, bracket in enumerate(brackets):
            inputs = _inputs(measures, plan, judge, bracket, b, arm.name)
            counted = inputs.matches if every_match else classify(inputs).contested
            if counted:
                ca[:, b] = kept(inputs.advised, counted).mean(axis=1)
        truth = np.array([measures[(arm.name, s)]["truth"] for s in range(plan.seeds)])
        table[arm.name] = ArmData(ca, truth)
    return table


def product_verdicts(
    measures: Measures, plan: Plan, judge: str, advice: TreeDocument, rng: np.random.Generator
) -> dict[str, dict[str, Any]]:
    """Each arm's verdict as the product gives it: its seeds against ``n1``'s on the advice's
    own bracket (bracket 0), contested matches picked by the pilots; with how many matches
    were informative and contested (what the verdict could count) and why it cannot tell."""
    found = {}
    for arm in plan.chosen:
        if arm.name != BASELINE:
            v = verdict(_inputs(measures, plan, judge, advice, 0, arm.name), rng)
            found[arm.name] = {
                "outcome": v.outcome,
                "delta": v.delta,
                "p_value": v.p_value,
                "contested": len(v.matches.contested),
                "informative": len(v.matches.contested) + len(v.matches.agreed),
                "reason": v.reason,
            }
    return found


def placebo_outcomes(
    measures: Measures, plan: Plan, judge: str, advice: TreeDocument, rng: np.random.Generator
) -> list[str]:
    """``n1``'s seeds split at random into halves, one half's verdict against the other's."""
    inputs = _inputs(measures, plan, judge, advice, 0, BASELINE)
    outcomes = []
    for _ in range(PLACEBO_SPLITS):
        order = rng.permutation(plan.seeds)
        half = plan.seeds // 2
        split = VerdictInputs(
            inputs.advice,
            inputs.baseline[order[:half]],
            inputs.baseline[order[half:]],
            inputs.pilot,
            inputs.matches,
            inputs.reward,
        )
        outcomes.append(verdict(split, rng).outcome)
    return outcomes


def judge_summary(
    measures: Measures, plan: Plan, judge: str, brackets: list[TreeDocument], seed: int = 0
) -> dict[str, Any]:
    """Every criterion under ``judge``, with what it rests on."""
    rng = np.random.default_rng(seed)
    table = arm_table(measures, plan, judge, brackets)
    verdicts = product_verdicts(measures, plan, judge, brackets[0], rng)
    outcomes = {arm: v["outcome"] for arm, v in verdicts.items()}
    agreement, within = criteria.truth_agreement(table)
    found = [
        _needs(table, criteria.separation, rng),
        _needs(table, criteria.dose_response, rng),
        agreement,
        _needs(table, criteria.rejection, rng),
        criteria.no_false_use(outcomes),
        criteria.placebo(placebo_outcomes(measures, plan, judge, brackets[0], rng)),
        criteria.hard_cases(outcomes, table),
    ]
    agreement_auc = _needs(
        arm_table(measures, plan, judge, brackets, every_match=True), criteria.separation, rng
    )
    return {
        "criteria": [asdict(c) for c in found],
        # reported, never decisive: issue 27 asks whether the uncorrected lead holds here
        "match_agreement_auc": asdict(agreement_auc),
        "rho_within_arms": within,
        "verdicts": verdicts,
        "ca": {arm: data.ca.tolist() for arm, data in table.items()},
        "truth": {arm: data.truth.tolist() for arm, data in table.items()},
        "known": {arm: criteria.known_direction(criteria.delta_truth(table, arm)) for arm in table},
    }


def _needs(
    table: Table,
    compute: Callable[[Table, np.random.Generator], Criterion],
    rng: np.random.Generator,
) -> Criterion:
    """``compute``'s criterion, or why it cannot be computed: an arm it reads is not trained."""
    name, arms = criteria.NEEDS[compute.__name__]
    missing = [a for a in arms if a not in table]
    if missing:
        return Criterion(name, None, note=f"arms not trained: {', '.join(missing)}")
    return compute(table, rng)
