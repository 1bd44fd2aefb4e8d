"""``acv validate`` end to end: pilots, brackets, every arm, measures, then ``summary.json`` and
``report.md`` (docs/validation.md). Every step resumes where an earlier call stopped."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from engine.provenance import git_commit
from engine.rl.logger import METRICS_FILE
from engine.treefile import load_tree
from engine.validation.analysis import judge_summary
from engine.validation.design import Plan
from engine.validation.figures import draw
from engine.validation.measure import JUDGES, complete_all
from engine.validation.runs import (
    arm_tasks,
    bracket_paths,
    make_brackets,
    measured,
    measures_path,
    pilot_tasks,
    prepare,
    read_json,
    run_dir,
    train_tasks,
)
from engine.validation.subsets import summary_subsets, table
from engine.validation.workers import Task, Workers
from engine.verdict import advice_scores, bracket_pairs, split_matches


def validate(
    out: Path,
    plan: Plan,
    *,
    workers: Workers = Workers(),
    command: str = "",
) -> dict[str, Any]:
    """Train what is not trained yet, measure, analyse; returns the summary it wrote, which
    names the ``command`` and the commit that wrote it."""
    prepare(out, plan)
    train_tasks(out, plan, pilot_tasks(plan), workers)
    brackets = make_brackets(out, plan)
    tasks = [*pilot_tasks(plan), *arm_tasks(plan)]
    measures = complete_all(out, plan, tasks, brackets, workers)
    summary: dict[str, Any] = json_safe(
        {
            "schema": "acv.validation/1",
            "command": command,
            "commit": git_commit(),
            "plan": plan.to_json(),
            "judges": {j: judge_summary(measures, plan, j, brackets) for j in JUDGES},
        }
    )
    summary["seed_subsets"] = summary_subsets(summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n")
    figures = draw(summary, out)
    (out / "report.md").write_text(report(summary, figures))
    return summary


def json_safe(value: Any) -> Any:
    """``value`` with NaN and infinities as null (None; ``np.array(..., dtype=float)`` reads
    them back as NaN): ``summary.json`` stays standard JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value  # str, int, bool, None


#: More than one metrics row (about 700 bytes each).
TAIL_BYTES = 4096


def steps_done(out: Path, plan: Plan, task: Task) -> int:
    """Env steps a run has logged so far (0 before its first update; the plan's budget once
    it is measured, with or without its folder): for progress bars."""
    path = run_dir(out, *task) / METRICS_FILE
    if measured(out, task):
        return plan.timesteps
    if not path.is_file():
        return 0
    with path.open("rb") as f:  # the last row only: polled every 2 s for every run
        f.seek(max(0, path.stat().st_size - TAIL_BYTES))
        lines = f.read().rstrip().splitlines()
    try:
        return int(json.loads(lines[-1])["timesteps"]) if lines else 0
    except (ValueError, KeyError):  # a line being written: the next poll reads it
        return 0


def status(out: Path, plan: Plan) -> list[str]:
    """One line per arm, pilots first: how many of its runs are measured (done, with or
    without their folders), and how far the others have trained here; then, once the pilots
    are measured, what each judge's verdict can count (:func:`countable`)."""
    tasks = [*pilot_tasks(plan), *arm_tasks(plan)]
    lines = []
    for name in dict.fromkeys(arm for arm, _ in tasks):
        seeds = [seed for arm, seed in tasks if arm == name]
        done = [seed for seed in seeds if measured(out, (name, seed))]
        steps = {seed: steps_done(out, plan, (name, seed)) for seed in seeds if seed not in done}
        line = f"{name}: {len(done)}/{len(seeds)} measured"
        line += f" (seeds {', '.join(map(str, done))})" if done else ""
        going = [
            f"seed {seed} at {n:,} of {plan.timesteps:,} steps" for seed, n in steps.items() if n
        ]
        lines.append(line + (f"; training {', '.join(going)}" if going else ""))
    return lines + countable(out, plan)


def countable(out: Path, plan: Plan) -> list[str]:
    """Per judge, the informative matches of the advice's bracket (0) and of all brackets, and
    how many of them the pilots contest: what the verdict and the criteria can count (fewer
    than 8: the bracket cannot tell, docs/method.md §2.11). Empty until the pilots are
    measured."""
    pilots, paths = pilot_tasks(plan), bracket_paths(out, plan)
    if not all(measured(out, t) for t in pilots) or not all(p.is_file() for p in paths):
        return []
    brackets = [load_tree(p) for p in paths]
    found = [read_json(measures_path(out, t)) for t in pilots]
    lines = []
    for judge in JUDGES:
        split = [
            split_matches(
                advice_scores(doc),
                np.mean([m["scores"][judge][b] for m in found], axis=0),
                bracket_pairs(doc),
            )
            for b, doc in enumerate(brackets)
        ]
        informative = [len(s.contested) + len(s.agreed) for s in split]
        contested = [len(s.contested) for s in split]
        lines.append(
            f"{judge}: bracket 0 has {informative[0]} informative matches, {contested[0]} "
            f"contested by the pilots; the {len(split)} brackets {sum(informative)} and "
            f"{sum(contested)}"
        )
    return lines


def report(summary: dict[str, Any], figures: Sequence[Path] = ()) -> str:
    """``report.md``: each criterion under each judge, pass or fail, with its interval, and
    the figures (paths relative to the report)."""
    plan = summary["plan"]
    lines = [
        f"# Validation: {plan['env_id']}, teacher `{plan['teacher']}`",
        "",
        f"{plan['seeds']} seeds per arm x {plan['timesteps']} steps, {plan['brackets']} "
        f"brackets of {plan['candidates']} informative candidates, {plan['pilot_seeds']} pilots; "
        "criteria and their thresholds: docs/validation.md §4.",
        "",
        f"`{summary['command']}` (commit `{summary['commit']}`)",
        "",
        "| judge | criterion | value | 95% interval | passed | note |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for judge, found in summary["judges"].items():
        for c in found["criteria"]:
            lines.append(
                f"| {judge} | {c['name']} | {_num(c['value'])} | {_interval(c)} | "
                f"{_passed(c['passed'])} | {c['note']} |"
            )
    lines += ["", "Reported, never decisive: the AUC of plain match agreement (every match, no"]
    lines += ["baseline correction), `p1-10` against `n1` + `n2`, per judge:", ""]
    for judge, found in summary["judges"].items():
        c = found["match_agreement_auc"]
        lines.append(f"- {judge}: {_num(c['value'])} {_interval(c)} {c['note']}".rstrip())
    if "seed_subsets" in summary:
        lines += ["", "The product's verdict with fewer seeds: of every choice of k matched seeds,"]
        lines += ['the share whose verdict says "used" or "went against":', ""]
        lines += [table(summary["seed_subsets"])]
    lines += ["", *(f"![{p.stem}](figures/{p.name})" for p in figures)]
    return "\n".join(lines) + "\n"


def _num(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def _interval(c: dict[str, Any]) -> str:
    return "" if c["low"] is None else f"[{c['low']:.3f}, {c['high']:.3f}]"


def _passed(passed: bool | None) -> str:
    return {True: "yes", False: "**no**", None: "could not compute"}[passed]
