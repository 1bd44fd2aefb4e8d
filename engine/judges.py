"""The agent's judges by name (no torch: the web tier lists and validates them).

- ``return`` and ``behaviour`` lead a verdict. Neither passed ``acv validate`` on known answers
  (docs/validation.md §5: no judge passes on Hopper-v5 or Humanoid-v5), and the pages say so.
- ``shaped``, ``shaping`` and ``shaped-value`` read the agent's shaped reward or critic: a
  diagnostic ("is your advice still in its reward?") that restates the advice and never leads a
  verdict. ``shaped-value`` was called ``value``; stored reports and callers may still say so.

The judges themselves are in :mod:`engine.rl.agent_judge`.
"""

from __future__ import annotations

from typing import Final, TypeVar

from engine.errors import InputError

T = TypeVar("T")

#: Every judge, the verdict's first.
JUDGES: tuple[str, ...] = ("return", "behaviour", "shaped", "shaping", "shaped-value")
#: The judges a verdict reads (neither passed the validation on known answers).
VERDICT_JUDGES: tuple[str, ...] = ("return", "behaviour")
#: The judges that read the agent's shaped reward or critic: a diagnostic, never a verdict.
DIAGNOSTIC_JUDGES: tuple[str, ...] = ("shaped", "shaping", "shaped-value")
#: Old name -> judge (stored reports and API callers from before the rename).
LEGACY_JUDGES: dict[str, str] = {"value": "shaped-value"}
#: The judge a single tree or curve shows when none is asked for.
DEFAULT_JUDGE: Final = "return"


def judge_name(judge: str) -> str:
    """``judge`` under its current name (``value`` is ``shaped-value``).

    Raises:
        InputError: not a judge.
    """
    judge = LEGACY_JUDGES.get(judge, judge)
    if judge not in JUDGES:
        raise InputError(f"unknown judge {judge!r}: expected one of {', '.join(JUDGES)}")
    return judge


def current_keys(by_judge: dict[str, T]) -> dict[str, T]:
    """A stored ``{judge: ...}`` map with legacy names replaced by the current ones."""
    return {LEGACY_JUDGES.get(k, k): v for k, v in by_judge.items()}


#: The column of a checkpoint report's per-candidate table (``engine.records.CandidateRow``)
#: that holds each judge's score.
JUDGE_COLUMNS: dict[str, str] = {
    "return": "env_return",
    "behaviour": "behaviour",
    "shaped": "shaped",
    "shaping": "shaping",
    "shaped-value": "value",
}
