"""The validation's figures, per judge, from ``summary.json`` alone: the dose response (Δ
against λ), ROC curves of positive against negative arms, and Δ against ΔU across runs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure  # the object API: no pyplot state, no display backend
from sklearn.metrics import roc_curve

from engine.validation.criteria import (
    DOSES,
    POSITIVE_TOP,
    SHUFFLED,
    ArmData,
    delta_truth,
    run_delta,
)
from engine.validation.design import BASELINE


def _table(found: dict[str, Any]) -> dict[str, ArmData]:
    return {
        arm: ArmData(np.array(ca, dtype=float), np.array(found["truth"][arm], dtype=float))
        for arm, ca in found["ca"].items()
    }


def draw(summary: dict[str, Any], out: Path) -> list[Path]:
    """``<out>/figures/<judge>.png`` for every judge of ``summary``."""
    folder = out / "figures"
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for judge, found in summary["judges"].items():
        table = _table(found)
        fig = Figure(figsize=(13, 4))
        left, middle, right = fig.subplots(1, 3)
        _dose(left, table)
        _roc(middle, table)
        _truth(right, table)
        fig.suptitle(f"{summary['plan']['env_id']}, judge {judge}")
        fig.tight_layout()
        paths.append(folder / f"{judge}.png")
        fig.savefig(paths[-1], dpi=100)
    return paths


def _dose(ax: Any, table: dict[str, ArmData]) -> None:
    for arm, dose in DOSES.items():
        if arm not in table:
            continue
        delta = run_delta(table, arm)
        delta = delta[np.isfinite(delta)]
        if len(delta):
            ax.scatter(np.full(len(delta), dose), delta, color="tab:blue", alpha=0.6)
            ax.errorbar(dose, delta.mean(), yerr=delta.std(), fmt="_k", capsize=6)
    ax.set(xscale="symlog", xlabel="scale λ of F", ylabel="Δ (CA minus n1's mean)")
    ax.set_title("dose response (seeds, mean ± sd)")


def _roc(ax: Any, table: dict[str, ArmData]) -> None:
    negatives = [a for a in (BASELINE, *SHUFFLED) if a in table]
    for arm in (a for a in table if a.startswith("p1") or a.startswith("bipars")):
        score = np.concatenate([table[arm].run_ca, *(table[a].run_ca for a in negatives)])
        label = np.r_[
            np.ones(len(table[arm].run_ca)), np.zeros(len(score) - len(table[arm].run_ca))
        ]
        ok = np.isfinite(score)
        if ok.any() and len(set(label[ok])) == 2:
            fpr, tpr, _ = roc_curve(label[ok], score[ok])
            ax.plot(fpr, tpr, label=arm, lw=2 if arm == POSITIVE_TOP else 1)
    ax.plot([0, 1], [0, 1], ":", color="grey")
    ax.set(xlabel="false positive rate", ylabel="true positive rate")
    ax.set_title(f"ROC: each arm against {' + '.join(negatives)}")
    _legend(ax)


def _truth(ax: Any, table: dict[str, ArmData]) -> None:
    for arm in (a for a in table if a != BASELINE):
        du = delta_truth(table, arm)
        ax.scatter(run_delta(table, arm)[: len(du)], du, label=arm, alpha=0.7)
    ax.axhline(0, color="grey", lw=0.5)
    ax.axvline(0, color="grey", lw=0.5)
    ax.set(xlabel="Δ (CA minus n1's mean)", ylabel="ΔU (teacher's score minus n1's)")
    ax.set_title("Δ against the ground truth, per run")
    _legend(ax)


def _legend(ax: Any) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
