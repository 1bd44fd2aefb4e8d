"""The numbers of a reproduction: returns, z, and conformance at every checkpoint.

Everything here reads the run folders :mod:`app.reproduce.plan` trained and the checkpoint
reports of :mod:`app.reproduce.checkpoints`; nothing is copied from the paper. Postures are
classed with the ``standing`` teacher's score (docs/method.md): ``straight`` when it is at
least :data:`STRAIGHT_SCORE`, else ``bent``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from engine.envs import env_model
from engine.judges import current_keys
from engine.rl.logger import read_metrics
from engine.teachers import standing_score
from engine.treefile import TreeDocument, tree_from_json

#: ``standing`` score from which a posture counts as straight (upright at standing height).
STRAIGHT_SCORE = 0.5


def posture_classes(doc: TreeDocument) -> dict[int, str]:
    """Candidate id -> ``"straight"`` or ``"bent"``."""
    qpos = np.stack([c.qpos for c in doc.candidates])
    scores = standing_score(qpos, env_model(doc.env_id))
    return {
        c.id: "straight" if s >= STRAIGHT_SCORE else "bent"
        for c, s in zip(doc.candidates, scores, strict=True)
    }


def bent_share(doc: TreeDocument, classes: dict[int, str]) -> dict[str, Any]:
    """Of the matches between a straight and a bent posture, how many the bent one won."""
    mixed = [(m, w) for m, w in doc.matches if classes[m.a] != classes[m.b]]
    bent = sum(classes[w] == "bent" for _, w in mixed)
    return {"matches": len(mixed), "bent_won": bent, "share": bent / len(mixed) if mixed else None}


def training_stats(run_dir: Path) -> dict[str, Any]:
    """Final true return (mean of the last 100 episodes), its best value, and z over training."""
    rows = read_metrics(run_dir)
    returns = [r["return_100"] for r in rows if r.get("return_100") is not None]
    z_means = [r["z_mean"] for r in rows]
    return {
        "timesteps": rows[-1]["timesteps"],
        "final_return_100": returns[-1] if returns else None,  # None: no episode ended
        "final_episode_length_100": recent_episode_length(rows),
        "best_return_100": max(returns, default=None),
        "z_mean_final": rows[-1]["z_mean"],
        "z_std_final": rows[-1]["z_std"],
        "z_mean_over_training": float(np.mean(z_means)),
        "z_min_over_training": float(np.min(z_means)),
        "z_max_over_training": float(np.max(z_means)),
    }


def recent_episode_length(rows: list[dict[str, Any]], episodes: int = 100) -> float | None:
    """Mean length of about the last ``episodes`` episodes (whole updates, from the end),
    the counterpart of ``return_100``; None when no episode ended."""
    total = count = 0
    for row in reversed(rows):
        if row.get("episodes") and row.get("episode_length") is not None:
            total += row["episode_length"] * row["episodes"]
            count += row["episodes"]
            if count >= episodes:
                break
    return total / count if count else None


def z_by_class(z: dict[int, float], classes: dict[int, str]) -> dict[str, float | None]:
    """Mean z_phi over the straight and over the bent candidates (None for an empty class)."""
    by_class = {k: [v for i, v in z.items() if classes[i] == k] for k in ("straight", "bent")}
    return {f"z_mean_{k}": float(np.mean(v)) if v else None for k, v in by_class.items()}


def checkpoint_point(step: int, report: dict[str, Any], classes: dict[int, str]) -> dict[str, Any]:
    """One checkpoint of one run: every judge's conformance in brief, and z per candidate.

    Args:
        report: :meth:`engine.rl.report.CheckpointReport.to_json` of the checkpoint.
        classes: the bracket's posture classes.
    """
    judges = {}
    for name, result in current_keys(report["judges"]).items():
        c, tree = result["conformance"], tree_from_json(result["tree"])
        judges[name] = {
            "n_agree": c["n_agree"],
            "n_matches": c["n_matches"],
            "match_agreement": c["match_agreement"],
            "contested_n": c["contested"]["n"],
            "contested_kept": c["contested"]["kept"],
            "contested_agreement": c["contested"]["agreement"],
            "kendall_tau_b": c["kendall_tau_b"],
            "same_champion": c["same_champion"],
            "champion": tree.tree.root,
            "bent_share": bent_share(tree, classes)["share"],
        }
    z = {row["id"]: row["z"] for row in report["candidates"]}
    return {
        "step": step,
        "judges": judges,
        "z": {str(k): v for k, v in z.items()},
        **z_by_class(z, classes),
    }


def seed_curve(reports: dict[int, dict[str, Any]], classes: dict[int, str]) -> list[dict[str, Any]]:
    """:func:`checkpoint_point` at every checkpoint of one run, in step order."""
    return [checkpoint_point(step, reports[step], classes) for step in sorted(reports)]
