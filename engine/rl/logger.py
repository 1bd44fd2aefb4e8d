"""The run's logs: ``metrics.jsonl`` (one row per update) and TensorBoard event files, which
also hold the run's hyper-parameters for the HPARAMS dashboard (:mod:`engine.rl.hparams`)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from engine.errors import InputError

if TYPE_CHECKING:
    from engine.rl.hparams import HParam

METRICS_FILE = "metrics.jsonl"
_EPISODE_KEYS = ("episode_returns", "episode_shaped_returns")


class RunLogger:
    """Appends metrics rows and mirrors them to TensorBoard.

    On resume, rows written after the checkpoint being resumed from (by the killed process)
    are dropped, a last row cut short by the kill too, and TensorBoard is told to purge its
    events after that step.

    Args:
        run_dir: the run directory.
        start: timesteps of the checkpoint the run continues from (0 for a new run).
        hparams: the run's hyper-parameters (:func:`engine.rl.hparams.config_hparams`),
            written again on resume, unchanged, so that a run started before they were logged
            has them too.
    """

    def __init__(self, run_dir: Path, start: int = 0, hparams: Mapping[str, HParam] | None = None):
        # Here, not at the top: reading metrics (read_metrics) must not import torch, since web
        # processes import run folders of runs trained before run state rows existed.
        from torch.utils.tensorboard import SummaryWriter

        from engine.rl.hparams import write_hparams

        self.path = Path(run_dir) / METRICS_FILE
        self._truncate(start)
        self.writer = SummaryWriter(str(run_dir), purge_step=start if start else None)
        if hparams is not None:
            write_hparams(self.writer, hparams)

    def _truncate(self, start: int) -> None:
        if not self.path.exists():
            self.path.touch()
            return
        keep = [line for line, row in _parse_lines(self.path) if row["timesteps"] <= start]
        self.path.write_text("".join(line + "\n" for line in keep))

    def write(self, row: dict[str, Any]) -> None:
        """Log one update: per-update scalars, and each finished episode at the update's step."""
        step = row["timesteps"]
        flat = {k: v for k, v in row.items() if k not in _EPISODE_KEYS}
        with self.path.open("a") as f:
            f.write(json.dumps(_finite(flat)) + "\n")
        for key, value in flat.items():
            if isinstance(value, int | float) and key not in ("timesteps", "time"):
                self.writer.add_scalar(f"train/{key}", value, step)
        for true, shaped in zip(*(row.get(k, []) for k in _EPISODE_KEYS), strict=True):
            self.writer.add_scalar("episode/true_return", true, step)
            self.writer.add_scalar("episode/shaped_return", shaped, step)

    def close(self) -> None:
        """Flush and close the TensorBoard writer."""
        self.writer.close()


def _finite(row: dict[str, Any]) -> dict[str, Any]:
    """NaN and infinities become null: ``metrics.jsonl`` stays strict JSON."""
    return {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in row.items()}


def read_metrics(run_dir: Path) -> list[dict[str, Any]]:
    """All rows of a run's ``metrics.jsonl`` (a torn last line is left out).

    Raises:
        InputError: a line other than the last is not JSON (the file is damaged).
    """
    return [row for _, row in _parse_lines(Path(run_dir) / METRICS_FILE)]


def _parse_lines(path: Path) -> list[tuple[str, dict[str, Any]]]:
    """Each line of a metrics file with its row, without a last line cut short by a kill."""
    lines = [line for line in path.read_text().splitlines() if line.strip()]
    rows = []
    for i, line in enumerate(lines):
        try:
            rows.append((line, json.loads(line)))
        except json.JSONDecodeError as exc:
            if i == len(lines) - 1:  # kill -9 mid-write: that update was never checkpointed
                break
            raise InputError(
                f"{path} line {i + 1} is not JSON: the metrics file is damaged"
            ) from exc
    return rows
