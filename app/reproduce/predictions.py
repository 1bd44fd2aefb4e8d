"""What the paper predicts next to what a reproduction measured.

Each claim names what it rests on: the arm, its seeds, the judge, the checkpoints and the
bracket, and the rule that decides whether it holds. Numbers over seeds are means with a
Student's t 95% interval (``[low, high]``; none for one seed).

A claim **holds** only against a baseline, with an interval that excludes it: chance (0.5) for
a share of matches, or the baseline arm, through Welch's t 95% interval of the difference of
per-seed values. A mean past a threshold is not enough, and one seed gives no interval, so a
claim on one seed never holds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from app.reproduce.intervals import diff_text, difference, stat_text

#: A share of matches that a coin would reach.
CHANCE = 0.5
#: "Close to the baseline": the difference's interval stays above -10% of the baseline's mean.
CLOSE = 0.10


def predictions(arms: dict[str, Any]) -> list[dict[str, Any]]:
    """The claims of the paper (and ACV's control), each measured on the arms."""
    return [
        claim
        for claim in (
            _case1(arms),
            _case2_bent(arms),
            _case2_anytime(arms),
            _case2_return(arms),
            _control_return(arms),
            _contested(arms),
            _used_at_all(arms),
            _agent_bracket(arms),
        )
        if claim is not None
    ]


def _case1(arms: dict[str, Any]) -> dict[str, Any] | None:
    arm = arms.get("case1-paper")
    if arm is None:
        return None
    shaped, behaviour = arm["final"]["main"]["shaped"], arm["final"]["main"]["behaviour"]
    contested = shaped["contested_kept"]
    return _claim(
        "Case 1 (F = R): the Agent Preference Tree matches the Human (good) Preference Tree",
        "the trees are the same",
        arm,
        "shaped, behaviour",
        "last",
        f"shaped: {stat_text(shaped['match_agreement'])} of matches kept; behaviour: "
        f"{stat_text(behaviour['match_agreement'])}; contested matches per seed: "
        f"{', '.join(contested)} (the good tree goes with R everywhere, so no match can show "
        "that the advice was used)",
        _mean(shaped["match_agreement"]) >= 0.8 and _above(shaped["match_agreement"], CHANCE),
        "shaped judge keeps at least 80% (mean), its interval above chance (0.5)",
    )


def _case2_bent(arms: dict[str, Any]) -> dict[str, Any] | None:
    arm = arms.get("case2")
    if arm is None:
        return None
    final = arm["final"]["main"]
    return _claim(
        "Case 2: the agent prefers bent postures to the advised straight ones",
        "the agent's tree ranks bent postures above straight ones",
        arm,
        "shaped, behaviour",
        "last",
        f"bent won {stat_text(final['shaped']['bent_share'], pct=True)} of "
        f"straight-vs-bent matches (shaped), "
        f"{stat_text(final['behaviour']['bent_share'], pct=True)} (behaviour)",
        _above(final["shaped"]["bent_share"], CHANCE),
        "bent's share (shaped judge) has its interval above chance (0.5)",
    )


def _case2_anytime(arms: dict[str, Any]) -> dict[str, Any] | None:
    case2, ppo = arms.get("case2"), arms.get("ppo")
    if case2 is None or ppo is None:
        return None
    shares = {name: _bent_checkpoints(arm) for name, arm in (("case2", case2), ("ppo", ppo))}
    diff = difference(shares["case2"], shares["ppo"])
    return _claim(
        "Case 2, anytime: the agent prefers bent postures at some checkpoint",
        "(the paper shows the trees at one point of training)",
        case2,
        "shaped",
        "every",
        "share of checkpoints where bent won most straight-vs-bent matches, per seed: "
        f"Case 2 {_shares(shares['case2'])}, PPO without advice {_shares(shares['ppo'])}; "
        f"difference {diff_text(diff)}",
        diff["ci_low"] is not None and diff["ci_low"] > 0,
        "Case 2's share is above PPO's (interval of the difference above 0)",
    )


def _bent_checkpoints(arm: dict[str, Any]) -> list[float]:
    """Per seed, the share of checkpoints where bent won most straight-vs-bent matches."""
    return [
        float(np.mean([(p["judges"]["shaped"]["bent_share"] or 0) > 0.5 for p in s["main"]]))
        for s in arm["seeds"]
    ]


def _shares(values: list[float]) -> str:
    return ", ".join(f"{v:.0%}" for v in values)


def _case2_return(arms: dict[str, Any]) -> dict[str, Any] | None:
    case2, ppo = arms.get("case2"), arms.get("ppo")
    if case2 is None or ppo is None:
        return None
    diff = difference(_per_seed(case2, "final_return_100"), _per_seed(ppo, "final_return_100"))
    margin = -CLOSE * abs(_mean(ppo["final_return"]))
    return _claim(
        "Case 2: the return is close to the no-advice baseline",
        "BiPaRS with bad advice reaches about the PPO return",
        case2,
        "(true return)",
        "last",
        f"{stat_text(case2['final_return'])} vs PPO {stat_text(ppo['final_return'])}; "
        f"difference {diff_text(diff)}",
        diff["ci_low"] is not None and diff["ci_low"] > margin,
        f"the difference's interval stays above -{CLOSE:.0%} of PPO's mean ({margin:.0f})",
    )


def _control_return(arms: dict[str, Any]) -> dict[str, Any] | None:
    control, case2 = arms.get("control"), arms.get("case2")
    if control is None or case2 is None:
        return None
    diff = difference(_per_seed(case2, "final_return_100"), _per_seed(control, "final_return_100"))
    return _claim(
        "Control: naive shaping with the standing advice does worse than Case 2",
        "not in the paper (ACV's control for what a learned z buys)",
        control,
        "(true return)",
        "last",
        f"{stat_text(control['final_return'])} vs Case 2 {stat_text(case2['final_return'])}; "
        f"Case 2 minus control {diff_text(diff)}",
        diff["ci_low"] is not None and diff["ci_low"] > 0,
        "Case 2's return is higher (interval of the difference above 0)",
    )


def _contested(arms: dict[str, Any]) -> dict[str, Any] | None:
    return _against_case2(
        arms,
        ("control", "control"),
        "control minus Case 2",
        "Case 2 rejects the advice where it goes against the reward, more than naive shaping",
        "implied: BiPaRS learns to ignore harmful advice",
        "Case 2 keeps fewer contested matches (interval of the difference above 0)",
    )


def _used_at_all(arms: dict[str, Any]) -> dict[str, Any] | None:
    return _against_case2(
        arms,
        ("ppo", "PPO without advice"),
        "difference",
        "The standing advice changed what the agent does, beyond what PPO without advice does",
        "implied by any verdict on advice use",
        "Case 2 keeps more than PPO (interval of the difference above 0)",
    )


def _against_case2(
    arms: dict[str, Any], other: tuple[str, str], gap: str, claim: str, paper: str, rule: str
) -> dict[str, Any] | None:
    """Case 2's share of contested matches kept (``behaviour``) against arm ``other`` (key,
    name); ``gap`` names the difference: ``difference`` is Case 2 minus the other, anything
    else the other minus Case 2. It holds when the difference's interval is above 0."""
    case2, base = arms.get("case2"), arms.get(other[0])
    if case2 is None or base is None:
        return None
    kept = [a["final"]["main"]["behaviour"]["contested_agreement"] for a in (case2, base)]
    first, second = (case2, base) if gap == "difference" else (base, case2)
    diff = difference(_contested_per_seed(first), _contested_per_seed(second))
    measured = (
        f"contested matches kept by behaviour: Case 2 {stat_text(kept[0])}, {other[1]} "
        f"{stat_text(kept[1])}; {gap} {diff_text(diff)}"
    )
    holds = diff["ci_low"] is not None and diff["ci_low"] > 0
    return _claim(claim, paper, case2, "behaviour", "last", measured, holds, rule)


def _agent_bracket(arms: dict[str, Any]) -> dict[str, Any] | None:
    arm = arms.get("case2")
    if arm is None:
        return None
    final = arm["final"]["agent"]
    return _claim(
        "Case 2 on postures a trained agent reaches (second bracket, from PPO's final policy)",
        "(not in the paper)",
        arm,
        "shaped, behaviour",
        "last",
        f"matches kept: shaped {stat_text(final['shaped']['match_agreement'])}, behaviour "
        f"{stat_text(final['behaviour']['match_agreement'])}; bent share (shaped) "
        f"{stat_text(final['shaped']['bent_share'], pct=True)}",
        _above(final["shaped"]["bent_share"], CHANCE),
        "bent's share (shaped) has its interval above chance (0.5) there too",
        bracket="agent",
    )


def _per_seed(arm: dict[str, Any], key: str) -> list[float | None]:
    return [s[key] for s in arm["seeds"]]


def _contested_per_seed(arm: dict[str, Any]) -> list[float | None]:
    """Per seed, the behaviour judge's share of contested matches kept, last checkpoint."""
    return [s["main"][-1]["judges"]["behaviour"]["contested_agreement"] for s in arm["seeds"]]


def _above(stat: dict[str, Any], baseline: float) -> bool:
    """The interval over seeds lies above ``baseline`` (never with one seed)."""
    return stat["ci_low"] is not None and stat["ci_low"] > baseline


def _claim(
    claim: str,
    paper: str,
    arm: dict[str, Any],
    judge: str,
    checkpoints: str,
    measured: str,
    holds: bool,
    rule: str,
    bracket: str = "main",
) -> dict[str, Any]:
    seeds = [s["seed"] for s in arm["seeds"]]
    steps = [s["main"][-1]["step"] for s in arm["seeds"]]
    where = (
        f"{arm['title']}; seeds {', '.join(map(str, seeds))}; judge {judge}; "
        + (
            f"checkpoint {max(steps):,}"
            if checkpoints == "last"
            else "every checkpoint"
            if checkpoints == "every"
            else checkpoints
        )
        + f"; {bracket} bracket"
    )
    return {
        "claim": claim,
        "paper": paper,
        "measured": measured,
        "rests_on": where,
        "holds": bool(holds),
        "rule": rule,
    }


def _mean(stat: dict[str, Any]) -> float:
    return float("nan") if stat["mean"] is None else stat["mean"]


# END
