"""The reproduction's outputs: figures, ``summary.json`` and ``README.md``.

Figures (PNG and SVG): ``figure3`` (learning curves of the core arms, mean over seeds with a
band from the lowest to the highest seed: the paper's Figure 3) and ``figure3-all`` (every
arm); ``conformance-<bracket>`` (match agreement and contested agreement of every judge across
training, same bands); ``figure4-<arm>[-behaviour]`` (the advice tree and the agent's tree of
seed 0 at the last checkpoint, thumbnails framed by posture class, overturned matches in red:
the paper's Figure 4). Every number comes from the checkpoint reports of
:mod:`app.reproduce.checkpoints`, computed once per checkpoint.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from app.core import figures
from app.reproduce.analysis import bent_share, posture_classes
from app.reproduce.arms import ARMS, Arm
from app.reproduce.checkpoints import BRACKETS, bracket_trees, compute_reports, report_path
from app.reproduce.figures import conformance_bands
from app.reproduce.markdown import readme
from app.reproduce.plan import ReproduceConfig
from app.reproduce.predictions import predictions
from app.reproduce.summary import arm_entry
from engine.provenance import git_commit
from engine.rl.plot import plot_runs
from engine.treefile import TreeDocument, tree_from_json

POSTURE_COLORS = {"straight": "#2f6fdf", "bent": "#e08a1e"}
THUMB_SIZE = 160
#: Arms whose trees are drawn (seed 0, last checkpoint), with the judges drawn.
FIGURE4 = {
    "case1-paper": ("shaped",),
    "case2": ("shaped", "behaviour"),
    "case2-mgl": ("shaped",),
    "control": ("shaped", "behaviour"),
}


def write_report(
    out: Path,
    config: ReproduceConfig,
    trees: dict[str, TreeDocument],
    command: str = "",
    jobs: int = 1,
) -> dict[str, Any]:
    """Judge every checkpoint (what is not cached yet), draw the figures, write the summary
    and the README."""
    compute_reports(out, config, trees, jobs)
    docs = bracket_trees(out, config, trees)
    classes = {b: posture_classes(docs[b]["standing"]) for b in BRACKETS}
    arms = {arm.name: arm_entry(out, config, arm, docs, classes) for arm in ARMS}
    summary = {
        "command": command,
        "commit": git_commit(),
        "config": config.to_json(),
        "advice": {
            f"{b}/{name}": {
                "judge": doc.judge,
                "champion": doc.tree.root,
                "bent_share": bent_share(doc, classes[b]),
            }
            for b in BRACKETS
            for name, doc in docs[b].items()
        },
        "postures": {b: {str(k): v for k, v in classes[b].items()} for b in BRACKETS},
        "arms": arms,
        "predictions": predictions(arms),
    }
    _draw_figures(out, arms, docs["main"], classes["main"])
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "README.md").write_text(readme(summary))
    return summary


def _draw_figures(
    out: Path, arms: dict[str, Any], trees: dict[str, TreeDocument], classes: dict[int, str]
) -> None:
    core = [arm for arm in ARMS if arm.core]
    for fmt in ("png", "svg"):
        plot_runs(
            [out / "runs" / a.name for a in core],
            out / f"figure3.{fmt}",
            [a.title for a in core],
            "Learning curves (true environment return)",
        )
        plot_runs(
            [out / "runs" / a.name for a in ARMS],
            out / f"figure3-all.{fmt}",
            [a.title for a in ARMS],
            "Learning curves, every arm",
        )
        for bracket in BRACKETS:
            (out / f"conformance-{bracket}.{fmt}").write_bytes(
                conformance_bands(arms, bracket, fmt)
            )
    thumbs = render_thumbs(out, trees["standing"])
    for arm in ARMS:
        for judge in FIGURE4.get(arm.name, ()):
            _draw_trees(out, arm, judge, trees[arm.compared_with], classes, thumbs, arms)


def _draw_trees(
    out: Path,
    arm: Arm,
    judge: str,
    advice: TreeDocument,
    classes: dict[int, str],
    thumbs: dict[int, np.ndarray],
    arms: dict[str, Any],
) -> None:
    """``figure4-<arm>[-<judge>]``: seed 0's tree at its last checkpoint next to the advice."""
    step = arms[arm.name]["seeds"][0]["main"][-1]["step"]
    report = json.loads(report_path(out, "main", arm, 0, step).read_text())
    agent = tree_from_json(report["judges"][judge]["tree"])
    c = report["judges"][judge]["conformance"]
    name = f"figure4-{arm.name}" + ("" if judge == "shaped" else f"-{judge}")
    for fmt in ("png", "svg"):
        data = figures.trees_side_by_side(
            advice,
            agent,
            thumbs=thumbs,
            highlights=_highlights(c),
            frame_colors={k: POSTURE_COLORS[v] for k, v in classes.items()},
            titles=(
                f"Human Preference Tree ({advice.judge} advice)",
                f"Agent Preference Tree ({agent.judge})",
            ),
            legend={
                "straight posture": POSTURE_COLORS["straight"],
                "bent posture": POSTURE_COLORS["bent"],
            },
            title=f"{arm.title}, seed 0, step {step:,}: kept {c['n_agree']} of "
            f"{c['n_matches']} matches, {c['contested']['kept']} of "
            f"{c['contested']['n']} contested",
            fmt=fmt,
        )
        (out / f"{name}.{fmt}").write_bytes(data)


def _highlights(c: dict[str, Any]) -> tuple[frozenset[int], frozenset[int]]:
    """The losers the human preferred against, and the winners the agent overturned."""
    human = {r["b"] if r["human_winner"] == r["a"] else r["a"] for r in c["rejected"]}
    return frozenset(human), frozenset(r["human_winner"] for r in c["rejected"])


def render_thumbs(out: Path, doc: TreeDocument) -> dict[int, np.ndarray]:
    """Render every candidate once (``thumbs/<id>.png``) and return the pixels."""
    from engine.render.service import RenderService

    folder = out / "thumbs"
    folder.mkdir(parents=True, exist_ok=True)
    with RenderService(cache=None) as service:
        images = service.render_many(
            doc.env_id,
            [(c.qpos, c.qvel) for c in doc.candidates],
            size=THUMB_SIZE,
            fmt="png",
            quality=True,
        )
    thumbs = {}
    for c, data in zip(doc.candidates, images, strict=True):
        (folder / f"{c.id}.png").write_bytes(data)
        thumbs[c.id] = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))
    return thumbs
