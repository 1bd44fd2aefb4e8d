"""What the paper predicts next to what a reproduction measured.

Each claim names what it rests on: the arm, its seeds, the judge, the checkpoints and the
bracket, and the rule that decides whether it holds. Numbers over seeds are means with a
Student's t 95% interval (``[low, high]``; none for one seed).
"""

from __future__ import annotations

from typing import Any


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
        _mean(shaped["match_agreement"]) >= 0.8,
        "shaped judge keeps at least 80% (mean)",
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
        _mean(final["shaped"]["bent_share"]) > 0.5,
        "bent wins most straight-vs-bent matches, shaped judge, mean over seeds",
    )


def _case2_anytime(arms: dict[str, Any]) -> dict[str, Any] | None:
    arm = arms.get("case2")
    if arm is None:
        return None
    counts = [
        sum(1 for p in s["main"] if (p["judges"]["shaped"]["bent_share"] or 0) > 0.5)
        for s in arm["seeds"]
    ]
    total = len(arm["seeds"][0]["main"])
    return _claim(
        "Case 2, anytime: the agent prefers bent postures at some checkpoint",
        "(the paper shows the trees at one point of training)",
        arm,
        "shaped",
        "every",
        "checkpoints where bent won most straight-vs-bent matches, per seed: "
        + ", ".join(f"{c}/{total}" for c in counts),
        all(c > 0 for c in counts),
        "at one checkpoint or more, in every seed",
    )


def _case2_return(arms: dict[str, Any]) -> dict[str, Any] | None:
    case2, ppo = arms.get("case2"), arms.get("ppo")
    if case2 is None or ppo is None:
        return None
    a, b = _mean(case2["final_return"]), _mean(ppo["final_return"])
    ratio = a / b if b and b > 0 else None
    return _claim(
        "Case 2: the return is close to the no-advice baseline",
        "BiPaRS with bad advice reaches about the PPO return",
        case2,
        "(true return)",
        "last",
        f"{stat_text(case2['final_return'])} vs PPO {stat_text(ppo['final_return'])}"
        + ("" if ratio is None else f" ({ratio:.2f} of PPO)"),
        ratio is not None and ratio >= 0.9,
        "at least 90% of PPO's mean final return",
    )


def _control_return(arms: dict[str, Any]) -> dict[str, Any] | None:
    control, case2 = arms.get("control"), arms.get("case2")
    if control is None or case2 is None:
        return None
    return _claim(
        "Control: naive shaping with the standing advice does worse than Case 2",
        "not in the paper (ACV's control for what a learned z buys)",
        control,
        "(true return)",
        "last",
        f"{stat_text(control['final_return'])} vs Case 2 {stat_text(case2['final_return'])}",
        _mean(control["final_return"]) < _mean(case2["final_return"]),
        "lower mean final return than Case 2",
    )


def _contested(arms: dict[str, Any]) -> dict[str, Any] | None:
    case2, control = arms.get("case2"), arms.get("control")
    if case2 is None or control is None:
        return None
    c2 = case2["final"]["main"]["behaviour"]["contested_agreement"]
    ctl = control["final"]["main"]["behaviour"]["contested_agreement"]
    return _claim(
        "Case 2 rejects the advice where it goes against the reward, more than naive shaping",
        "implied: BiPaRS learns to ignore harmful advice",
        case2,
        "behaviour",
        "last",
        f"contested matches kept by behaviour: Case 2 {stat_text(c2)}, control {stat_text(ctl)}",
        _mean(c2) < _mean(ctl),
        "Case 2 keeps fewer contested matches than the control",
    )


def _used_at_all(arms: dict[str, Any]) -> dict[str, Any] | None:
    case2, ppo = arms.get("case2"), arms.get("ppo")
    if case2 is None or ppo is None:
        return None
    c2 = case2["final"]["main"]["behaviour"]["contested_agreement"]
    base = ppo["final"]["main"]["behaviour"]["contested_agreement"]
    return _claim(
        "The standing advice changed what the agent does, beyond what PPO without advice does",
        "implied by any verdict on advice use",
        case2,
        "behaviour",
        "last",
        f"contested matches kept by behaviour: Case 2 {stat_text(c2)}, PPO without advice "
        f"{stat_text(base)}",
        c2["ci_low"] is not None and base["ci_high"] is not None and c2["ci_low"] > base["ci_high"],
        "Case 2's interval lies above PPO's (no overlap)",
    )


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
        _mean(final["shaped"]["bent_share"]) > 0.5,
        "bent wins most straight-vs-bent matches there too (shaped, mean)",
        bracket="agent",
    )


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


def stat_text(stat: dict[str, Any], pct: bool = False) -> str:
    """``0.62 [0.51, 0.73] (3 seeds)``; percentages with ``pct``."""
    if stat["mean"] is None:
        return "n/a"
    f = (
        (lambda v: f"{100 * v:.0f}%")
        if pct
        else (lambda v: f"{v:.2f}" if abs(v) < 10 else f"{v:.0f}")
    )
    ci = "" if stat["ci_low"] is None else f" [{f(stat['ci_low'])}, {f(stat['ci_high'])}]"
    return f"{f(stat['mean'])}{ci} ({stat['n']} seed{'s' * (stat['n'] != 1)})"
