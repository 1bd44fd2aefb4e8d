"""Learning curves: true episodic return against timesteps (the paper's Figure 3).

Each curve is one run directory, or a folder of run directories (seeds of one
configuration), drawn as the mean over seeds with a band from the lowest to the highest seed.
The y value at an update is the mean true return of the last 100 finished episodes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # the object API: no pyplot state, no display backend

from engine.errors import InputError
from engine.rl.logger import METRICS_FILE, read_metrics


def seed_runs(path: Path) -> list[Path]:
    """The run directories a curve is made of: ``path`` itself or its sub-runs.

    Raises:
        InputError: ``path`` holds no ``metrics.jsonl`` at either level.
    """
    path = Path(path)
    if (path / METRICS_FILE).is_file():
        return [path]
    runs = (
        sorted(p for p in path.iterdir() if (p / METRICS_FILE).is_file()) if path.is_dir() else []
    )
    if not runs:
        raise InputError(f"{path} is not a training run (no {METRICS_FILE}) nor a folder of runs")
    return runs


def curve(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """Timesteps and mean return of the last 100 episodes, at updates that have one."""
    rows = [r for r in read_metrics(run_dir) if r.get("return_100") is not None]
    if not rows:
        raise InputError(f"{run_dir} has no finished episode yet")
    return (
        np.array([r["timesteps"] for r in rows], dtype=float),
        np.array([r["return_100"] for r in rows], dtype=float),
    )


def seed_band(curves: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, ...]:
    """Mean, min and max over seeds on a shared grid (up to the shortest run), shape (G,)."""
    end = min(x[-1] for x, _ in curves)
    start = max(x[0] for x, _ in curves)
    grid = np.linspace(start, end, 200) if end > start else np.array([end])
    ys = np.stack([np.interp(grid, x, y) for x, y in curves])
    return grid, ys.mean(0), ys.min(0), ys.max(0)


def plot_runs(
    paths: list[Path], out: Path, labels: list[str] | None = None, title: str | None = None
) -> Path:
    """Draw one curve per path into ``out`` (PNG, or any format matplotlib knows by suffix)."""
    if labels is not None and len(labels) != len(paths):
        raise InputError(f"{len(labels)} labels for {len(paths)} runs")
    fig = Figure(figsize=(7, 4.2), dpi=120)
    ax = fig.subplots()
    for i, path in enumerate(paths):
        runs = seed_runs(path)
        label = labels[i] if labels else Path(path).name
        grid, mean, lo, hi = seed_band([curve(r) for r in runs])
        (line,) = ax.plot(grid, mean, label=f"{label} ({len(runs)} seed{'s' * (len(runs) > 1)})")
        if len(runs) > 1:
            ax.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.2, linewidth=0)
    ax.set_xlabel("timesteps")
    ax.set_ylabel("episodic return (true reward, last 100 episodes)")
    ax.set_title(title or "Learning curves")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    return Path(out)
