"""``results/README.md``: the reproduction's summary as Markdown, written from ``summary.json``.
"""

from __future__ import annotations

from typing import Any


def readme(summary: dict[str, Any]) -> str:
    """The results page of one reproduction."""
    cfg = summary["config"]
    parts = [
        "# ACV reproduction of the paper's experiments\n",
        f"`{summary['command'] or 'acv reproduce'}`, report written on commit "
        f"`{summary['commit']}` (a resumed reproduction trains nothing again; see each run's "
        "checkpoints for when it trained): "
        f"{cfg['env_id']}, {cfg['timesteps']:,} env steps per agent, {cfg['seeds']} seed(s), "
        f"one bracket of {cfg['candidates']} candidates (p = {cfg['p']}, seed "
        f"{cfg['bracket_seed']}). Every number below comes from this run (`summary.json`).\n",
        "## Paper vs measured\n",
        _table(["claim", "paper", "measured", "holds?"],
               [[p["claim"], p["paper"], p["measured"],
                 ("yes" if p["holds"] else "**no**") + f" ({p['rule']})"]
                for p in summary["predictions"]]),
        "## Final returns and z\n",
        _table(["agent", "final return (last 100 episodes)", "best", "episode length",
                "return per step", "z final (mean ± std)", "z mean over training"],
               [_arm_row(a) for a in summary["arms"].values()]),
        "![learning curves](figure3.png)\n",
        "## Preference trees at the last checkpoint\n",
        _table(["agent", "matches kept", "Kendall tau-b", "tree edit distance",
                "same champion", "z at straight / bent candidates"],
               [_tree_row(a) for a in summary["arms"].values() if a["advice"]]),
        "Frames: blue = straight posture, orange = bent (the `standing` score >= 0.5); red "
        "edges = matches the agent decided the other way.\n",
        *[_figure4(name, a) for name, a in summary["arms"].items() if a["advice"]],
        "## Conformance across training\n",
        "![conformance](conformance.png)\n",
        *[_curve(name, a) for name, a in summary["arms"].items() if a["advice"]],
    ]
    return "\n".join(parts)


def _figure4(name: str, arm: dict[str, Any]) -> str:
    """The arm's trees at the last checkpoint, and where it kept the fewest matches."""
    step = arm["seeds"][0].get("least_conformant_step")
    least = "" if step is None else (
        f"\nAt step {step:,}, where it kept the fewest matches:\n\n"
        f"![{name} at step {step}](figure4-{name}-least.png)\n")
    return f"![{name}](figure4-{name}.png)\n{least}"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _arm_row(arm: dict[str, Any]) -> list[str]:
    s = arm["seeds"]
    spread = f" ± {_num(arm['final_return_std'])}" if len(s) > 1 else ""
    return [arm["title"], f"{_num(arm['final_return_mean'])}{spread}",
            " / ".join(_num(x["best_return_100"]) for x in s),
            " / ".join(_num(x["final_episode_length_100"]) for x in s),
            " / ".join(_per_step(x) for x in s),
            " / ".join(f"{x['z_mean_final']:.2f} ± {x['z_std_final']:.2f}" for x in s),
            " / ".join(f"{x['z_mean_over_training']:.2f}" for x in s)]


def _per_step(seed: dict[str, Any]) -> str:
    """Final return over final episode length: Humanoid's healthy bonus alone gives 5."""
    ret, length = seed["final_return_100"], seed["final_episode_length_100"]
    return "n/a" if ret is None or not length else f"{ret / length:.2f}"


def _tree_row(arm: dict[str, Any]) -> list[str]:
    final = arm["seeds"][0]["final"]
    c = final["conformance"]
    tau = "undefined" if c["kendall_tau_b"] is None else f"{c['kendall_tau_b']:.3f}"
    return [arm["title"], f"{c['n_agree']}/{c['n_matches']} ({c['match_agreement']:.2f})", tau,
            f"{c['tree_edit_distance']:.3f}", "yes" if c["same_champion"] else "no",
            f"{_num(final['z_mean_straight'], 2)} / {_num(final['z_mean_bent'], 2)}"]


def _curve(name: str, arm: dict[str, Any]) -> str:
    rows = [[f"{r['step']:,}", f"{r['n_agree']}/{r['n_matches']}",
             "undefined" if r["kendall_tau_b"] is None else f"{r['kendall_tau_b']:.2f}",
             f"{r['tree_edit_distance']:.2f}", "yes" if r["same_champion"] else "no",
             "n/a" if r["bent_share"] is None else f"{100 * r['bent_share']:.0f}%",
             f"{_num(r['z_mean_straight'], 2)} / {_num(r['z_mean_bent'], 2)}"]
            for r in arm["seeds"][0]["conformance_curve"]]
    return (f"<details><summary>{arm['title']}: every checkpoint</summary>\n\n"
            + _table(["step", "kept", "tau-b", "TED", "same champion",
                      "bent won (straight vs bent)", "z straight / bent"], rows)
            + "\n</details>\n")


def _num(x: float | None, digits: int = 1) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"
