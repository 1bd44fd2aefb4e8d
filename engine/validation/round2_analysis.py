"""Round 2's analysis from the saved measures alone (docs/validation.md §6.4-6.5): the
criteria under the primary and, labelled diagnostic, under every other judge and score; the
product's verdict per arm and bracket; and what is reported, never deciding.

Written before any of round 2's runs, with the criteria of :mod:`round2_criteria`; it reads
``measures/`` and ``advice/`` only, so it runs again anywhere without training.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from engine.errors import InputError
from engine.treefile import TreeDocument, load_tree
from engine.validation.round2 import EVAL_SEED0, known_direction
from engine.validation.round2_criteria import Bracket, Round, criteria
from engine.validation.round2_runs import Round2Plan, measured, measures_path
from engine.validation.validate import json_safe
from engine.verdict_bracket import (
    AlignmentVerdict,
    Stage,
    alignment,
    alignment_verdict,
    tree_values,
)

#: The primary's score, then the diagnostics' (docs/validation.md §6.2).
PRIMARY = "behaviour"
SCORES = (PRIMARY, "behaviour-nearest", "return", "shaped-value")


def trees(out: Path, b: int) -> tuple[TreeDocument, TreeDocument]:
    """Bracket ``b``'s advice and its shuffled tree, as the arms trained on them."""
    return load_tree(out / "advice" / f"advice-b{b}.json"), load_tree(
        out / "advice" / f"shuffled-b{b}.json"
    )


def arm_measures(out: Path, label: str, seeds: int) -> list[dict[str, Any]]:
    """The measures of run ``label``'s first ``seeds`` seeds (100, 101, ...), in seed order.

    Raises:
        InputError: naming the runs not measured yet.
    """
    tasks = [(label, EVAL_SEED0 + k) for k in range(seeds)]
    missing = [f"{lab}-{s}" for lab, s in tasks if not measured(out, (lab, s))]
    if missing:
        raise InputError(f"not measured yet: {', '.join(missing)}")
    return [json.loads(measures_path(out, t).read_text()) for t in tasks]


def arm_rows(
    found: list[dict[str, Any]],
    bracket: str,
    own: np.ndarray,
    other: np.ndarray,
    score: str,
    teacher: str,
) -> np.ndarray:
    """An arm's ``(3, seeds)``: ``r`` with the bracket's advice and with its shuffled tree
    under ``score``, and U."""
    scores = np.array([m["scores"][bracket][score] for m in found])  # (k, N)
    truth = np.array([m["truth"][teacher] for m in found])
    return np.stack([alignment(scores, own), alignment(scores, other), truth])


def build_round(out: Path, plan: Round2Plan, score: str) -> Round:
    """The deciding arms of every advice bracket, with the shared ``n1``."""
    n1 = arm_measures(out, "n1", _seeds(plan, "n1"))
    found: Round = []
    for b in range(plan.brackets):
        advice, shuffled = (tree_values(t) for t in trees(out, b))
        bracket: Bracket = {"n1": arm_rows(n1, f"b{b}", advice, shuffled, score, plan.teacher)}
        for arm in plan.design:
            if arm.deciding and b in arm.brackets:
                runs = arm_measures(out, f"{arm.name}.b{b}", arm.seeds)
                bracket[arm.name] = arm_rows(runs, f"b{b}", advice, shuffled, score, plan.teacher)
        found.append(bracket)
    return found


def _seeds(plan: Round2Plan, name: str) -> int:
    return next(arm.seeds for arm in plan.design if arm.name == name)


def bracket_verdicts(
    out: Path, plan: Round2Plan, score: str, rng: np.random.Generator
) -> dict[str, dict[str, AlignmentVerdict]]:
    """The product's verdict of every arm (reported ones too) against ``n1``'s seeds 100-104,
    per bracket; an outcome word for the primary only."""
    n1 = arm_measures(out, "n1", 5)
    stage: Stage = "primary" if score == PRIMARY else "diagnostic"
    found: dict[str, dict[str, AlignmentVerdict]] = {}
    for b in range(plan.brackets):
        values = tree_values(trees(out, b)[0])
        base = np.array([m["scores"][f"b{b}"][score] for m in n1])
        found[f"b{b}"] = {
            arm.name: alignment_verdict(
                values,
                _scores(out, f"{arm.name}.b{b}", arm.seeds, f"b{b}", score),
                base,
                rng,
                stage=stage,
            )
            for arm in plan.design
            if b in arm.brackets and arm.name != "bipars-em-standing-shuffled"
        }
    return found


def _scores(out: Path, label: str, seeds: int, bracket: str, score: str) -> np.ndarray:
    return np.array([m["scores"][bracket][score] for m in arm_measures(out, label, seeds)])


def standing_check(out: Path, plan: Round2Plan, rng: np.random.Generator) -> dict[str, Any]:
    """§6.5: ``bipars-em`` on a shuffled ``standing`` tree, judged on the ``standing`` tree
    against ``n1`` (100-104), and U under ``standing`` for both."""
    standing = tree_values(load_tree(out / "brackets" / "standing.json"))
    arm = arm_measures(out, "bipars-em-standing-shuffled.b0", 5)
    n1 = arm_measures(out, "n1", 5)
    rows = [np.array([m["scores"]["standing"][PRIMARY] for m in runs]) for runs in (arm, n1)]
    verdict = alignment_verdict(standing, rows[0], rows[1], rng)
    truth = [[m["truth"]["standing"] for m in runs] for runs in (arm, n1)]
    return {"verdict": verdict.to_json(), "truth": {"arm": truth[0], "n1": truth[1]}}


def summarize(out: Path, plan: Round2Plan, rng: np.random.Generator) -> dict[str, Any]:
    """Every criterion under every score, the verdicts, and the ground truth per arm."""
    judged = {}
    for score in SCORES:
        round_ = build_round(out, plan, score)
        judged[score] = {
            "role": "primary" if score == PRIMARY else "diagnostic",
            "criteria": [asdict(c) for c in criteria(round_, rng)],
            "verdicts": {
                b: {arm: v.to_json() for arm, v in arms.items()}
                for b, arms in bracket_verdicts(out, plan, score, rng).items()
            },
        }
    round_ = build_round(out, plan, PRIMARY)
    truth = {
        f"b{b}": {
            a: known_direction(rows[2], bracket["n1"][2])
            for a, rows in bracket.items()
            if a != "n1"
        }
        for b, bracket in enumerate(round_)
    }
    summary = {
        "schema": "acv.validation-round2/1",
        "plan": asdict(plan),
        "scores": judged,
        "truth": truth,
    }
    if plan.standing_bracket is not None:
        summary["standing"] = standing_check(out, plan, rng)
    return summary


def report(summary: dict[str, Any]) -> str:
    """``report.md``: the criteria per score (the primary first), then the verdicts."""
    plan = summary["plan"]
    lines = [f"# Validation round 2: {plan['env_id']}, teacher `{plan['teacher']}`", ""]
    lines += ["Criteria and thresholds: docs/validation.md §6.4. Only the primary decides.", ""]
    lines += ["| score | role | criterion | value | 95% interval | passed | note |"]
    lines += ["| --- | --- | --- | --- | --- | --- | --- |"]
    for score, found in summary["scores"].items():
        for c in found["criteria"]:
            value = "n/a" if c["value"] is None else f"{c['value']:.3f}"
            interval = "" if c["low"] is None else f"[{c['low']:.3f}, {c['high']:.3f}]"
            lines.append(
                f"| {score} | {found['role']} | {c['name']} | {value} | {interval} | "
                f"{'yes' if c['passed'] else '**no**'} | {c['note']} |"
            )
    lines += ["", "The product's verdict per bracket and arm (primary):", ""]
    for b, arms in summary["scores"][PRIMARY]["verdicts"].items():
        lines += [
            f"- {b}, {arm}: {v['text']} (U: {summary['truth'][b].get(arm, 'n/a')})"
            for arm, v in arms.items()
        ]
    return "\n".join(lines) + "\n"


def write(out: Path, plan: Round2Plan, rng: np.random.Generator) -> dict[str, Any]:
    """``summary.json`` and ``report.md`` in ``out``."""
    summary = summarize(out, plan, rng)
    text = json.dumps(json_safe(summary), indent=1, allow_nan=False)
    (out / "summary.json").write_text(text + "\n")
    (out / "report.md").write_text(report(summary))
    return summary
