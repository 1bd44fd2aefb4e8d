"""The reproduction's outputs: figures, ``summary.json`` and ``README.md``.

Figures (PNG and SVG): ``figure3`` (learning curves, the paper's Figure 3),
``figure4-<arm>`` (the advice tree and the agent's tree side by side, thumbnails framed by
posture class, overturned matches in red: the paper's Figure 4) and ``conformance`` (match
agreement at every checkpoint).
"""

from __future__ import annotations

import io
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from app.reproduce.analysis import (
    bent_share,
    conformance_curve,
    final_agent,
    posture_classes,
    training_stats,
)
from app.reproduce.markdown import readme
from app.reproduce.plan import ARMS, Arm, ReproduceConfig, run_path
from app.services import figures
from app.services.run_report import highlights
from engine.conformance import compare
from engine.rl.agent_judge import agent_tree
from engine.rl.plot import plot_runs
from engine.treefile import TreeDocument, dump_tree

POSTURE_COLORS = {"straight": "#2f6fdf", "bent": "#e08a1e"}
THUMB_SIZE = 160


def write_report(out: Path, config: ReproduceConfig, trees: dict[str, TreeDocument],
                 command: str = "") -> dict[str, Any]:
    """Analyse every run of ``out``, draw the figures, write the summary and the README."""
    (out / "trees").mkdir(parents=True, exist_ok=True)
    classes = posture_classes(trees["standing"])
    thumbs = render_thumbs(out, trees["standing"])
    arms = {arm.name: _arm_summary(out, config, arm, trees, classes, thumbs) for arm in ARMS}
    summary = {
        "command": command, "commit": git_commit(), "config": config.to_json(),
        "advice": {name: {"judge": doc.judge, "champion": doc.tree.root,
                          "bent_share": bent_share(doc, classes)}
                   for name, doc in trees.items()},
        "postures": {str(k): v for k, v in classes.items()},
        "arms": arms,
    }
    summary["predictions"] = predictions(summary)
    _draw_curves(out, arms)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "README.md").write_text(readme(summary))
    return summary


def _arm_summary(out: Path, config: ReproduceConfig, arm: Arm, trees: dict[str, TreeDocument],
                 classes: dict[int, str], thumbs: dict[int, np.ndarray]) -> dict[str, Any]:
    """Per-seed statistics of one arm; its trees and figures for seed 0."""
    seeds = []
    for seed in range(config.seeds):
        run = run_path(out, arm, seed)
        entry = {"seed": seed, **training_stats(run)}
        if arm.advice is not None:
            advice = trees[arm.advice]
            agent_doc, entry["final"] = final_agent(run, advice, classes)
            entry["conformance_curve"] = conformance_curve(run, advice, classes)
            dump_tree(agent_doc, out / "trees" / f"{arm.name}-seed{seed}.json")
            if seed == 0:
                _draw_trees(out, f"figure4-{arm.name}", arm.title, advice, agent_doc,
                            entry["final"]["conformance"], classes, thumbs)
                entry["least_conformant_step"] = _draw_least_conformant(
                    out, arm, run, advice, entry["conformance_curve"], classes, thumbs)
        seeds.append(entry)
    finals = [s["final_return_100"] for s in seeds if s["final_return_100"] is not None]
    return {"title": arm.title, "algo": arm.algo, "advice": arm.advice, "seeds": seeds,
            "final_return_mean": float(np.mean(finals)) if finals else None,
            "final_return_std": float(np.std(finals)) if finals else None}


def render_thumbs(out: Path, doc: TreeDocument) -> dict[int, np.ndarray]:
    """Render every candidate once (``thumbs/<id>.png``) and return the pixels."""
    from engine.render.service import RenderService

    folder = out / "thumbs"
    folder.mkdir(parents=True, exist_ok=True)
    with RenderService(cache=None) as service:
        images = service.render_many(doc.env_id, [(c.qpos, c.qvel) for c in doc.candidates],
                                     size=THUMB_SIZE, fmt="png", quality=True)
    thumbs = {}
    for c, data in zip(doc.candidates, images, strict=True):
        (folder / f"{c.id}.png").write_bytes(data)
        thumbs[c.id] = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
    return thumbs


def _draw_least_conformant(out: Path, arm: Arm, run: Path, advice: TreeDocument,
                           curve: list[dict[str, Any]], classes: dict[int, str],
                           thumbs: dict[int, np.ndarray]) -> int | None:
    """Figure 4 at the checkpoint where the agent kept the fewest matches (the earliest of
    equals), when it kept fewer there than at the last one: "anytime" verification shows
    the whole path, not only where it ended."""
    least = min(curve, key=lambda r: (r["match_agreement"], r["step"]))
    if least["match_agreement"] >= curve[-1]["match_agreement"]:
        return None
    doc = agent_tree(run, least["step"], "shaped", advice)
    _draw_trees(out, f"figure4-{arm.name}-least", f"{arm.title}, step {least['step']:,}",
                advice, doc, compare(advice, doc).to_json(), classes, thumbs)
    return least["step"]


def _draw_trees(out: Path, name: str, title: str, advice: TreeDocument, agent: TreeDocument,
                c: dict[str, Any], classes: dict[int, str],
                thumbs: dict[int, np.ndarray]) -> None:
    """``<name>.png`` and ``.svg``: the two trees side by side, framed by posture class."""
    for fmt in ("png", "svg"):
        data = figures.trees_side_by_side(
            advice, agent, thumbs=thumbs, highlights=highlights(c),
            frame_colors={k: POSTURE_COLORS[v] for k, v in classes.items()},
            titles=(f"Human Preference Tree ({advice.judge} advice)",
                    f"Agent Preference Tree ({agent.judge})"),
            legend={"straight posture": POSTURE_COLORS["straight"],
                    "bent posture": POSTURE_COLORS["bent"]},
            title=f"{title}: the agent kept {c['n_agree']} of {c['n_matches']} matches",
            fmt=fmt)
        (out / f"{name}.{fmt}").write_bytes(data)


def _draw_curves(out: Path, arms: dict[str, Any]) -> None:
    """Figure 3 and the conformance curves (seed 0), as PNG and SVG."""
    runs = [out / "runs" / arm.name for arm in ARMS]
    series = [figures.Series(arms[arm.name]["title"],
                             [r["step"] for r in arms[arm.name]["seeds"][0]["conformance_curve"]],
                             [r["match_agreement"]
                              for r in arms[arm.name]["seeds"][0]["conformance_curve"]])
              for arm in ARMS if arm.advice is not None]
    for fmt in ("png", "svg"):
        plot_runs(runs, out / f"figure3.{fmt}", [arm.title for arm in ARMS],
                  "Learning curves (true environment return)")
        (out / f"conformance.{fmt}").write_bytes(figures.line_chart(
            series, xlabel="timesteps", ylabel="match agreement with the advice",
            title="Conformance across training (seed 0)", fmt=fmt, ylim=(0, 1.02)))


def predictions(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """What the paper predicts next to what this run measured (seed 0's trees)."""
    arms = summary["arms"]
    case1 = arms["case1"]["seeds"][0]["final"]
    case2 = arms["case2"]["seeds"][0]["final"]
    c1, c2 = case1["conformance"], case2["conformance"]
    ppo, case2_return = arms["ppo"]["final_return_mean"], arms["case2"]["final_return_mean"]
    ratio = case2_return / ppo if ppo and case2_return is not None and ppo > 0 else None
    human_bent = summary["advice"]["standing"]["bent_share"]["share"]
    agent_bent = case2["bent_share"]["share"]
    control = arms["control"]["final_return_mean"]
    bent_at = [r for r in arms["case2"]["seeds"][0]["conformance_curve"]
               if r["bent_share"] is not None and r["bent_share"] > 0.5]
    return [
        {"claim": "Case 1: the Agent Preference Tree matches the Human Preference Tree",
         "paper": "the trees are the same",
         "measured": f"{c1['n_agree']}/{c1['n_matches']} matches kept, same champion: "
                     f"{'yes' if c1['same_champion'] else 'no'}",
         "holds": c1["match_agreement"] >= 0.8, "rule": "at least 80% of the matches kept"},
        {"claim": "Case 2: the agent prefers bent postures to the advised straight ones",
         "paper": "the agent's tree ranks bent postures above straight ones",
         "measured": f"bent won {_pct(agent_bent)} of straight-vs-bent matches for the agent, "
                     f"{_pct(human_bent)} for the advice; {c2['n_agree']}/{c2['n_matches']} "
                     "matches kept",
         "holds": agent_bent is not None and agent_bent > 0.5,
         "rule": "bent wins most straight-vs-bent matches in the agent's tree"},
        {"claim": "Case 2, anytime: the agent prefers bent postures at some checkpoint",
         "paper": "(the paper shows the trees at one point of training)",
         "measured": f"bent won most straight-vs-bent matches at {len(bent_at)} of "
                     f"{len(arms['case2']['seeds'][0]['conformance_curve'])} checkpoints"
                     + (f" (steps {bent_at[0]['step']:,} to {bent_at[-1]['step']:,})"
                        if bent_at else ""),
         "holds": bool(bent_at),
         "rule": "bent wins most straight-vs-bent matches at one checkpoint or more"},
        {"claim": "Case 2: the return is close to the no-advice baseline",
         "paper": "BiPaRS with bad advice reaches about the PPO return",
         "measured": f"{_num(case2_return)} vs {_num(ppo)} ("
                     + ("no positive PPO return to compare with" if ratio is None
                        else f"{ratio:.2f} of PPO") + ")",
         "holds": ratio is not None and ratio >= 0.9,
         "rule": "at least 90% of PPO's final return"},
        {"claim": "Control: naive shaping with the standing advice does worse than Case 2",
         "paper": "not in the paper (ACV's control for what z buys)",
         "measured": f"{_num(control)} vs {_num(case2_return)}",
         "holds": None not in (control, case2_return) and control < case2_return,
         "rule": "lower final return than Case 2"},
    ]


def _num(value: float | None) -> str:
    return "n/a (no episode finished)" if value is None else f"{value:.1f}"


def _pct(share: float | None) -> str:
    return "n/a" if share is None else f"{100 * share:.0f}%"


def git_commit() -> str | None:
    """The commit of the code that wrote the report (``+dirty`` with local changes)."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=root, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+dirty" if dirty else "")
