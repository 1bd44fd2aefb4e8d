"""The replay on round 1's committed runs (docs/validation.md §7.3, issue 41 §4).

Each arm's 5 runs against ``n1``'s 5, on the teacher's own score U of every run (``truth`` in
``docs/validation/humanoid-*/measures/<arm>-<seed>.json``):

1. **Ground truth.** U's own exact two-sided permutation test, 5 against 5 (C(10, 5) = 252
   assignments, :func:`engine.evaluation.stats.exact_p` on the U values): "more" / "less" at
   p < 0.05 by the sign of the difference in mean U, "unknown" otherwise.
2. **The evaluation, simulated.** The exact design: the pairs of
   :func:`engine.evaluation.design.evaluator_pairs` over the 10 runs, 10 evaluators x 20 pairs,
   answered by a simulated evaluator (:data:`JUDGES`) built on a Bradley-Terry teacher reading
   U at scale :data:`~engine.evaluation.simulate.U_SCALE`, decided by
   :func:`engine.evaluation.outcome.evaluate` (its default 2,000 bootstrap draws).
3. **Replays.** Replay ``r`` of every arm and evaluator shares one design (common random
   numbers: its pair seed is :func:`design_seed`); the answers draw from their own generator
   ``default_rng([seed, r, crc32(arm), crc32(evaluator)])`` and the bootstrap from another, so
   a replay's "more" / "less" never depends on the bootstrap's size or on ``R``.

The **unrelated taste** judges runs by scores independent of the arms: ``N(0, RUN_SD_U)`` per
run, drawn per replay, read by the same teacher; its own test is the exact test on those
scores. A taste unrelated to the advice as the issue means it (``standing`` judging
``orthogonal`` runs) needs U under both teachers for the same runs, which only round 2 keeps.

Simulated evaluators check statistics and plumbing, never that people see the difference.
"""

from __future__ import annotations

import argparse
import json
import time
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from engine.evaluation.design import evaluator_pairs
from engine.evaluation.outcome import evaluate
from engine.evaluation.simulate import (
    RUN_SD_U,
    U_SCALE,
    CantTellWhenClose,
    Evaluator,
    Lapses,
    NoisyTeacher,
    SideBias,
    simulate_answers,
)
from engine.evaluation.stats import exact_p

BASELINE = "n1"
RUNS_PER_ARM = 5
N_EVALUATORS = 10
PAIRS_PER_EVALUATOR = 20
ALPHA = 0.05
#: §7.3: false "more"/"less" on arms U cannot tell apart, at most the level plus 0.03.
FALSE_RATE_MAX = ALPHA + 0.03
REPLAYS = 200
SEED = 41
N_BOOT = 2000
#: One letter per outcome in a cell's ``outcomes`` string, in replay order.
CODES = {"more": "M", "less": "L", "no_different": "N", "cannot_tell": "C"}
#: One letter per ground truth ("unknown": U's test does not reject).
TRUTH_CODES = {"more": "M", "less": "L", "unknown": "U"}
ROOT = Path(__file__).resolve().parents[2]
MEASURES = {
    "orthogonal": ROOT / "docs/validation/humanoid-orthogonal/measures",
    "standing": ROOT / "docs/validation/humanoid-standing/measures",
}


@dataclass(frozen=True)
class Judge:
    """A simulated evaluator of the replay: its name, how it answers, what it reads."""

    name: str
    evaluator: Evaluator
    description: str
    reads_taste: bool = False


TEACHER = NoisyTeacher(U_SCALE)
JUDGES: tuple[Judge, ...] = (
    Judge("teacher", TEACHER, "reference: Bradley-Terry on U, P(a) = expit(dU / 0.1)"),
    Judge("side-bias", SideBias(0.65, TEACHER), "30% the left run whatever is shown, else the "
          "teacher: 65% left on even pairs (simulate.SideBias)"),
    Judge("side-bias-blind", SideBias(0.65, Lapses(1.0)), "the literal reading: 65% left "
          "whatever is shown, never looking (SideBias over a fair coin)"),
    Judge("lapses", Lapses(0.2, TEACHER), "20% of answers a fair coin, else the teacher"),
    Judge("cant-tell", CantTellWhenClose(0.05, TEACHER), "'can't tell' when |dU| < 0.05, "
          "else the teacher"),
    Judge("unrelated-taste", TEACHER, "the teacher on scores N(0, 0.0685) per run drawn per "
          "replay, independent of the arms (round 1 has U under one teacher per run)", True),
)  # fmt: skip
#: The judges bound by the false-positive criterion (§7.3 rows 1-3, and the literal reading).
FALSE_POSITIVE_JUDGES = ("side-bias", "side-bias-blind", "lapses", "cant-tell")
ADVISED = np.arange(2 * RUNS_PER_ARM) < RUNS_PER_ARM


def load_u(folder: Path) -> dict[str, np.ndarray]:
    """U (``truth``) of every run in a measures folder, by arm, in seed order.

    A file ``<arm>-<seed>.json`` is one run; arms with another count of runs than
    :data:`RUNS_PER_ARM` (the two ``pilot`` runs) are kept, and left out by :func:`arms`.
    """
    runs: dict[str, list[tuple[int, float]]] = {}
    for path in folder.glob("*.json"):
        arm, seed = path.stem.rsplit("-", 1)
        runs.setdefault(arm, []).append((int(seed), float(json.loads(path.read_text())["truth"])))
    return {arm: np.array([u for _, u in sorted(pairs)]) for arm, pairs in sorted(runs.items())}


def arms(u: Mapping[str, np.ndarray]) -> list[str]:
    """The arms compared with :data:`BASELINE`: every other arm of 5 runs."""
    return [a for a, v in u.items() if a != BASELINE and len(v) == len(u[BASELINE]) == 5]


def ground_truth(scores: np.ndarray, alpha: float = ALPHA) -> tuple[str, float]:
    """``(truth, p)`` of the exact test on 10 scores, the first 5 advised (module docstring)."""
    p = float(exact_p(scores, ADVISED))
    diff = scores[ADVISED].mean() - scores[~ADVISED].mean()
    return ("unknown" if p >= alpha else "more" if diff > 0 else "less"), p


def design_seed(seed: int, replay: int) -> int:
    """Replay ``replay``'s pair seed, shared by every arm and evaluator."""
    return int(np.random.SeedSequence([seed, replay]).generate_state(1)[0])


def _generators(seed: int, replay: int, key: str, judge: str) -> list[np.random.Generator]:
    """The answers' and the bootstrap's generators of one replay of one cell."""
    ids = [seed, replay, zlib.crc32(key.encode()), zlib.crc32(judge.encode())]
    return [np.random.default_rng([*ids, stream]) for stream in (0, 1)]


def replay_once(
    u: np.ndarray,
    judge: Judge,
    key: str,
    seed: int,
    replay: int,
    n_boot: int = N_BOOT,
    taste: np.ndarray | None = None,
) -> tuple[str, str]:
    """One simulated evaluation: ``(outcome code, own-test code)`` (:data:`CODES`,
    :data:`TRUTH_CODES`); the own test is the judge's taste's, or U's. A judge that reads a
    taste reads ``taste`` (the runs' U under another teacher) where given, else scores drawn
    independently of the arms."""
    answers_rng, boot_rng = _generators(seed, replay, key, judge.name)
    scores = u
    if judge.reads_taste:
        scores = taste if taste is not None else answers_rng.normal(0.0, RUN_SD_U, len(u))
    seed_r = design_seed(seed, replay)
    plans = [evaluator_pairs(len(u), PAIRS_PER_EVALUATOR, e, seed_r) for e in range(N_EVALUATORS)]
    given = simulate_answers(scores, plans, judge.evaluator, answers_rng)
    result = evaluate(given, ADVISED, boot_rng, "advisor", n_boot=n_boot)
    return CODES[result.outcome], TRUTH_CODES[ground_truth(scores)[0]]


def replay_cell(
    u: np.ndarray,
    judge: Judge,
    key: str,
    seed: int,
    replays: Sequence[int],
    n_boot: int = N_BOOT,
    taste: np.ndarray | None = None,
) -> dict[str, Any]:
    """Replays of one arm (``u``: its 5 runs' U, then ``n1``'s) by one judge, summarised."""
    codes = [replay_once(u, judge, key, seed, r, n_boot, taste) for r in replays]
    outcomes = "".join(c for c, _ in codes)
    cell: dict[str, Any] = {
        "evaluator": judge.name,
        "rates": {o: outcomes.count(c) / len(outcomes) for o, c in CODES.items()},
        "outcomes": outcomes,
    }
    if judge.reads_taste:
        own = "".join(o for _, o in codes)
        cell["own_test"] = own
        cell["own_more_rate"] = own.count("M") / len(own)
        cell["more_without_own_more"] = sum(
            c == "M" != o for c, o in zip(outcomes, own, strict=True)
        )
    return cell


def run(
    folders: Mapping[str, Path],
    replays: int = REPLAYS,
    seed: int = SEED,
    n_boot: int = N_BOOT,
    judges: Sequence[Judge] = JUDGES,
) -> list[dict[str, Any]]:
    """Every arm of every teacher's measures folder against its ``n1``, by every judge."""
    out = []
    for teacher, folder in folders.items():
        u = load_u(folder)
        for arm in arms(u):
            scores = np.concatenate([u[arm], u[BASELINE]])
            out.append(replay_arm(f"{teacher}/{arm}", scores, judges, seed, replays, n_boot))
    return out


def replay_arm(
    key: str,
    scores: np.ndarray,
    judges: Sequence[Judge],
    seed: int,
    replays: int,
    n_boot: int,
    taste: np.ndarray | None = None,
) -> dict[str, Any]:
    """One arm against its baseline (``scores``: 5 runs' U, then the baseline's 5), by every
    judge: the ground truth and every judge's cell."""
    truth, p = ground_truth(scores)
    cells = [replay_cell(scores, j, key, seed, range(replays), n_boot, taste) for j in judges]
    row = {"arm": key, "U": scores[ADVISED].tolist(), "U_n1": scores[~ADVISED].tolist()}
    return {**row, "U_p": p, "ground_truth": truth, "cells": cells}


def criteria(arms_out: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The declared criteria of §7.3, one row per (criterion, arm, judge) they bind."""
    rows = []
    for arm in arms_out:
        for cell in arm["cells"]:
            name, rates = cell["evaluator"], cell["rates"]
            if name in FALSE_POSITIVE_JUDGES and arm["ground_truth"] == "unknown":
                value = rates["more"] + rates["less"]
                rows.append(_row("false more/less", arm, name, value, FALSE_RATE_MAX))
            if "more_without_own_more" in cell:  # a judge that reads a taste
                count = cell["more_without_own_more"]
                rows.append(_row("more without its own test's more", arm, name, count, 0))
    return rows


def _row(
    what: str, arm: Mapping[str, Any], judge: str, value: float, limit: float
) -> dict[str, Any]:
    """One criterion's verdict."""
    return {"criterion": what, "arm": arm["arm"], "evaluator": judge, "value": value,
            "limit": limit, "passed": bool(value <= limit)}  # fmt: skip


NOTES = [
    "Simulated evaluators check statistics and plumbing, never that people see the difference.",
    "Run-level U (the teacher's own score of each run), not the stills or clips people see.",
    "unrelated-taste: scores independent of the arms, since U under both teachers for the same "
    "runs (standing judging orthogonal runs) only exists in round 2; its own test is the exact "
    "test on its scores.",
    "pilot-*: 2 runs, not an arm of 5; outside §7.3.",
    "Ground truth 'unknown': the evaluation is reported there, not scored; the false-positive "
    "criterion reads its more/less rate.",
]


def write_result(
    out: Path,
    arms_out: Sequence[Mapping[str, Any]],
    judges: Sequence[Judge],
    started: float,
    head: Mapping[str, Any],
    tail: Mapping[str, Any],
) -> None:
    """A replay's JSON: ``head`` (the command, replays, seed), the design and evaluators,
    ``tail``, every arm, the criteria, and the time since ``started`` (``perf_counter``)."""
    rows = criteria(arms_out)
    result = {
        **head, "n_boot": N_BOOT, "alpha": ALPHA,
        "design": {"runs_per_arm": RUNS_PER_ARM, "evaluators": N_EVALUATORS,
                   "pairs_per_evaluator": PAIRS_PER_EVALUATOR, "u_scale": U_SCALE},
        "evaluators": {j.name: j.description for j in judges},
        **tail, "arms": arms_out, "criteria": rows,
        "all_passed": all(r["passed"] for r in rows),
        "runtime_s": round(time.perf_counter() - started, 1),
    }  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m engine.evaluation.replay --out docs/validation/evaluation/replay.json``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--replays", type=int, default=REPLAYS)
    parser.add_argument("--seed", type=int, default=SEED)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    arms_out = run(MEASURES, args.replays, args.seed)
    command = "python -m engine.evaluation.replay --out " + str(args.out)
    head = {"command": command, "replays": args.replays, "seed": args.seed}
    write_result(args.out, arms_out, JUDGES, start, head, {"notes": NOTES})


if __name__ == "__main__":
    main()
