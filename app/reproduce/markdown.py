"""``results/README.md``: the reproduction's summary as Markdown, written from ``summary.json``."""

from __future__ import annotations

from typing import Any

from app.reproduce.intervals import stat_text
from app.reproduce.summary import JUDGES

CANNOT_SHOW = """\
## What the Agent Preference Tree can and cannot show

The tree replays the human's bracket with a score the agent gives each candidate. What it
shows depends on that score. With the *shaped* judge the score is R + z F, and at a candidate F
is the advice's own tree reward: with z near 1 the tree restates the advice whatever the agent
learned, so keeping the advice under this judge is weak evidence. The *shaped-value* judge reads
the critic, which learns R + z F and so partly restates the advice too; the *behaviour* judge
reads where the agent's own rollouts go (a revealed preference), which can disagree with the
advice, and that is the evidence. Only *contested*
matches, where the advice goes against the environment's reward, can tell an agent that used
the advice from one that followed the reward; a bracket with none of them cannot tell at all.
The 16 candidates are one bracket: a Wilson interval over its 15 matches is an interval over
matches for one agent, not over seeds, and the intervals here over 3 seeds are wide.
"""


def readme(summary: dict[str, Any]) -> str:
    """The results page of one reproduction."""
    cfg, arms = summary["config"], summary["arms"]
    parts = [
        "# ACV reproduction of the paper's experiments\n",
        f"`{summary['command'] or 'acv reproduce'}`, report written on commit "
        f"`{summary['commit']}`: {cfg['env_id']}, {cfg['timesteps']:,} env steps per run, "
        f"{cfg['seeds']} seed(s) for the core arms and {cfg['extra_seeds']} for the others, one "
        f"bracket of {cfg['candidates']} candidates (p = {cfg['p']}, seed {cfg['bracket_seed']})"
        ". Over seeds: mean and Student's t 95% interval `[low, high]`. A claim holds only "
        "against a baseline (chance, or the no-advice arm) with an interval that excludes it: "
        "Welch's t 95% interval of the difference over seeds; one seed never holds. Every "
        "number comes from `summary.json`.\n",
        "## Paper vs measured\n",
        _predictions_table(summary["predictions"]),
        "## Final returns and z\n",
        _table(
            ["arm", "final return (last 100 episodes)", "per seed", "z final (mean ± std)"],
            [_return_row(a) for a in arms.values()],
        ),
        "![learning curves](figure3.png)\n\n![every arm](figure3-all.png)\n",
        *[_conformance_section(arms, bracket) for bracket in ("main", "agent")],
        "## z at each candidate (seed 0, last checkpoint, main bracket)\n",
        _z_table(arms, summary["postures"]["main"]),
        "## The trees (seed 0, last checkpoint)\n",
        "Frames: blue = straight posture, orange = bent (the `standing` score >= 0.5); red "
        "= matches the agent decided the other way.\n",
        *[
            f"![{name}](figure4-{name}.png)\n"
            for name in ("case1-paper", "case2", "case2-mgl", "control")
        ],
        "![case2, behaviour judge](figure4-case2-behaviour.png)\n",
        "![control, behaviour judge](figure4-control-behaviour.png)\n",
        CANNOT_SHOW,
    ]
    return "\n".join(parts)


def _predictions_table(predictions: list[dict[str, Any]]) -> str:
    """Each claim of the paper next to what was measured, and whether it holds."""
    return _table(
        ["claim", "paper", "measured", "rests on", "holds?"],
        [
            [
                p["claim"],
                p["paper"],
                p["measured"],
                p["rests_on"],
                ("yes" if p["holds"] else "**no**") + f" ({p['rule']})",
            ]
            for p in predictions
        ],
    )


def _conformance_section(arms: dict[str, Any], bracket: str) -> str:
    title = {
        "main": "the shared advice bracket",
        "agent": "the second bracket (candidates from PPO's final policy)",
    }[bracket]
    rows = [
        [
            a["title"],
            judge,
            stat_text(a["final"][bracket][judge]["match_agreement"]),
            ", ".join(a["final"][bracket][judge]["contested_kept"]),
            stat_text(a["final"][bracket][judge]["bent_share"], pct=True),
        ]
        for a in arms.values()
        for judge in JUDGES
        if has_judge(a, judge)
    ]
    return (
        f"## Conformance at the last checkpoint, {title}\n\n"
        + _table(
            [
                "arm",
                "judge",
                "matches kept",
                "contested kept (per seed)",
                "bent won (straight vs bent)",
            ],
            rows,
        )
        + f"\n![conformance](conformance-{bracket}.png)\n"
    )


def has_judge(arm: dict[str, Any], judge: str) -> bool:
    """Whether ``judge`` means anything for ``arm``: without advice z = 0, so every
    ``shaping`` score is 0 and its tree only shows how ties are broken."""
    return not (judge == "shaping" and arm["algo"] == "ppo")


def _return_row(arm: dict[str, Any]) -> list[str]:
    s = arm["seeds"]
    return [
        arm["title"],
        stat_text(arm["final_return"]),
        " / ".join(_num(x["final_return_100"]) for x in s),
        " / ".join(f"{x['z_mean_final']:.2f} ± {x['z_std_final']:.2f}" for x in s),
    ]


def _z_table(arms: dict[str, Any], postures: dict[str, str]) -> str:
    advised = [a for a in arms.values() if a["algo"].startswith("bipars")]
    ids = sorted(postures, key=int)
    rows = [
        [f"#{i}", postures[i], *(_num(a["seeds"][0]["main"][-1]["z"][i], 2) for a in advised)]
        for i in ids
    ]
    return _table(["candidate", "posture", *(a["title"] for a in advised)], rows)


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _num(x: float | None, digits: int = 1) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"
