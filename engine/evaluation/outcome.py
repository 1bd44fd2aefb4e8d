"""The evaluation's outcome and its sentence (issue 41 §2, "Outcomes"), over the statistics
of :mod:`engine.evaluation.stats`.

Declared before any evaluation is run, checked in this order:

1. **cannot tell** when there are no answers, fewer than 2 runs per arm have answers, or the
   exact test cannot go below ``alpha`` with those runs (3 runs against 2: p >= 0.1);
2. **more** / **less** when the exact permutation p < ``alpha``, by the statistic's sign;
3. **no different** when p >= ``alpha`` and the bootstrap interval lies inside
   ``[-margin, +margin]`` (default 0.1 of win rate);
4. **cannot tell** otherwise, with the reason: the interval is too wide for the answers there
   are.

Worded by evaluator kind: the **advisor** (whose tree trained the agents) hears about "what
you asked for", **others** about "what the instruction asks for".
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np

from engine.errors import InputError
from engine.evaluation.stats import (
    Answers,
    Rate,
    between_arm_win_rate,
    interval,
    permutation_p,
    side_bias,
    smallest_p,
    statistic,
    win_rates,
)

Outcome = Literal["more", "less", "no_different", "cannot_tell"]
EvaluatorKind = Literal["advisor", "others"]
#: evaluator kind -> (whose advice, what they judge), for the sentence.
WORDS: dict[str, tuple[str, str]] = {
    "advisor": ("your advice", "what you asked for"),
    "others": ("the advice", "what the instruction asks for"),
}


def guard_reason(n_answers: int, k_advised: int, k_baseline: int, alpha: float) -> str | None:
    """Why no test can decide (rule 1), or None."""
    if n_answers == 0:
        return "no answers yet"
    if min(k_advised, k_baseline) < 2:
        return (
            f"fewer than 2 runs per arm have answers ({k_advised} advised, "
            f"{k_baseline} without advice)"
        )
    if (low := smallest_p(k_advised, k_baseline)) >= alpha:
        return (
            f"with {k_advised} and {k_baseline} runs the exact test cannot go below p = {low:.3f}"
        )
    return None


def decide(
    p: float, statistic: float, ci: tuple[float, float], margin: float, alpha: float
) -> tuple[Outcome, str | None]:
    """``(outcome, reason)`` by rules 2-4 (module docstring)."""
    if p < alpha:
        return ("more" if statistic > 0 else "less"), None
    if -margin <= ci[0] and ci[1] <= margin:
        return "no_different", None
    reason = f"the interval [{ci[0]:+.2f}, {ci[1]:+.2f}] reaches beyond ±{margin:.2f}"
    return "cannot_tell", reason + ": too few answers or runs to tell"


def sentence(outcome: Outcome, kind: EvaluatorKind, reason: str | None = None) -> str:
    """The outcome in words, by evaluator kind (issue 41 §2, "Outcomes")."""
    advice, what = WORDS[kind]
    return {
        "more": f"The agent trained with {advice} does more of {what}.",
        "less": f"The agent trained with {advice} does less of {what}.",
        "no_different": f"The agent trained with {advice} is no different in {what} "
        "from the agent trained without it.",
        "cannot_tell": f"Cannot tell whether the agent trained with {advice} does more of "
        f"{what}: {reason}.",
    }[outcome]


@dataclass(frozen=True)
class EvaluationResult:
    """The evaluation's answer and everything it rests on.

    Attributes:
        outcome: ``more``, ``less``, ``no_different`` or ``cannot_tell``.
        sentence: the outcome in words for ``evaluator_kind``.
        reason: why "cannot tell" (None otherwise).
        evaluator_kind: ``advisor`` or ``others``.
        statistic: advised minus baseline mean win rate (None without runs in both arms).
        p_value: the exact permutation p (None when rule 1 decides).
        interval: the bootstrap interval of ``statistic`` (None when rule 1 decides).
        win_rates: per run, its win rate (None without answers), length ``n_runs``.
        side_bias: left-side win rate of within-arm answers.
        between_arm: the advised runs' win rate in between-arm answers.
        n_answers: answers counted.
        n_evaluators: distinct evaluators among them.
        alpha: the test's level.
        margin: the "no different" margin on the statistic.
    """

    outcome: Outcome
    sentence: str
    reason: str | None
    evaluator_kind: EvaluatorKind
    statistic: float | None
    p_value: float | None
    interval: tuple[float, float] | None
    win_rates: tuple[float | None, ...]
    side_bias: Rate
    between_arm: Rate
    n_answers: int
    n_evaluators: int
    alpha: float
    margin: float

    def to_json(self) -> dict[str, Any]:
        """JSON-ready data for the API (tuples as lists, rates as objects)."""
        out = asdict(self)
        out["interval"] = None if self.interval is None else list(self.interval)
        out["win_rates"] = list(self.win_rates)
        return out


def evaluate(
    answers: Answers,
    advised: np.ndarray,
    rng: np.random.Generator,
    evaluator_kind: EvaluatorKind,
    margin: float = 0.1,
    alpha: float = 0.05,
    n_boot: int = 2000,
) -> EvaluationResult:
    """The evaluation's answer: the declared statistic (:mod:`engine.evaluation.stats`) and
    outcome rule (module docstring).

    Args:
        answers: every answer counted (gold items and practice already left out).
        advised: True for the advised arm's runs, bool shape ``(n_runs,)``.
        rng: draws the bootstrap.
        evaluator_kind: ``advisor`` (the person whose tree trained the agents) or ``others``.
        margin: the interval must lie inside ``±margin`` for "no different".
        alpha: the test's level.
        n_boot: bootstrap draws.
    """
    advised = np.asarray(advised, dtype=bool)
    if answers.n and int(max(answers.a.max(), answers.b.max())) >= len(advised):
        raise InputError(f"an answer names a run outside the {len(advised)} runs")
    if evaluator_kind not in WORDS or not (0 < alpha < 1 and margin >= 0):
        raise InputError(f"need an evaluator kind in {sorted(WORDS)}, 0 < alpha < 1, margin >= 0")
    rates = win_rates(answers, len(advised))
    outcome, reason, p, ci = _decision(answers, advised, rng, margin, alpha, n_boot)
    return EvaluationResult(
        outcome=outcome,
        sentence=sentence(outcome, evaluator_kind, reason),
        reason=reason,
        evaluator_kind=evaluator_kind,
        statistic=statistic(rates, advised),
        p_value=p,
        interval=ci,
        win_rates=tuple(None if np.isnan(r) else float(r) for r in rates),
        side_bias=side_bias(answers, advised),
        between_arm=between_arm_win_rate(answers, advised),
        n_answers=answers.n,
        n_evaluators=len(np.unique(answers.evaluator)),
        alpha=alpha,
        margin=margin,
    )


def _decision(
    answers: Answers,
    advised: np.ndarray,
    rng: np.random.Generator,
    margin: float,
    alpha: float,
    n_boot: int,
) -> tuple[Outcome, str | None, float | None, tuple[float, float] | None]:
    """``(outcome, reason, p, interval)`` by rules 1-4. p is reported whenever both arms have
    a run with answers, the interval only when rule 1 lets the test decide."""
    rates = win_rates(answers, len(advised))
    present = ~np.isnan(rates)
    k_a, k_b = int((advised & present).sum()), int((~advised & present).sum())
    reason = guard_reason(answers.n, k_a, k_b, alpha)
    p = permutation_p(answers, advised) if min(k_a, k_b) else None
    if reason is not None or p is None:  # p is None only when rule 1 holds
        return "cannot_tell", reason, p, None
    ci = interval(answers, advised, rng, n_boot)
    return (*decide(p, float(statistic(rates, advised) or 0.0), ci, margin, alpha), p, ci)
