"""The conformance figure of a reproduction: every judge, every arm, bands across seeds."""

from __future__ import annotations

import io
from typing import Any

from matplotlib.figure import Figure  # the object API: no pyplot state, no display backend

from app.reproduce.markdown import has_judge
from app.reproduce.summary import JUDGES

PANELS = (("match_agreement", "match agreement"), ("contested_agreement", "contested matches kept"))


def conformance_bands(arms: dict[str, Any], bracket: str, fmt: str = "svg") -> bytes:
    """A grid of judges (rows) by metric (columns): per arm the mean over seeds, with a band
    from the lowest to the highest seed where it has more than one."""
    fig = Figure(figsize=(11, 2.6 * len(JUDGES)), dpi=100)
    axes = fig.subplots(len(JUDGES), len(PANELS), sharex=True, squeeze=False)
    for row, judge in enumerate(JUDGES):
        for col, (key, label) in enumerate(PANELS):
            ax = axes[row][col]
            for i, arm in enumerate(arms.values()):  # one colour per arm in every panel
                if has_judge(arm, judge):
                    _draw_arm(ax, arm, bracket, judge, key, f"C{i}")
            ax.set_ylim(-0.03, 1.03)
            ax.set_title(f"{judge} judge: {label}", fontsize=10)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("timesteps")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8)
    fig.suptitle(
        f"Conformance across training ({bracket} bracket): mean over seeds, band = "
        "lowest to highest seed"
    )
    fig.tight_layout(rect=(0, 0.08, 1, 0.97))
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt)
    return buf.getvalue()


def _draw_arm(ax, arm: dict[str, Any], bracket: str, judge: str, key: str, color: str) -> None:
    points = [p for p in arm["curve"][bracket][judge] if p[key]["mean"] is not None]
    if not points:
        return
    x = [p["step"] for p in points]
    per_seed = [[_value(s, bracket, judge, key, step) for step in x] for s in arm["seeds"]]
    (line,) = ax.plot(
        x,
        [p[key]["mean"] for p in points],
        linewidth=1.4,
        color=color,
        label=f"{arm['title']} ({len(arm['seeds'])} seed{'s' * (len(arm['seeds']) > 1)})",
    )
    if len(per_seed) > 1:
        lows = [min(v for v in col if v is not None) for col in zip(*per_seed, strict=True)]
        highs = [max(v for v in col if v is not None) for col in zip(*per_seed, strict=True)]
        ax.fill_between(x, lows, highs, color=line.get_color(), alpha=0.15, linewidth=0)


def _value(seed: dict[str, Any], bracket: str, judge: str, key: str, step: int) -> float | None:
    return next(p["judges"][judge][key] for p in seed[bracket] if p["step"] == step)
