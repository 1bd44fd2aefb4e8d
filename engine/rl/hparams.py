"""Runs in TensorBoard's HPARAMS dashboard (issue 44 §5): each run's hyper-parameters, and the
verdict's numbers beside them.

- Every run writes its :class:`~engine.rl.config.TrainConfig` into its own event files as the
  hparams plugin's *session start* (:class:`engine.rl.logger.RunLogger`), so each run under a
  log dir is one row of the dashboard, with the last value of each of its scalars
  (``train/episodic_return``, ...) as its metrics.
- ``acv verdict`` writes its numbers into the runs it scored, at the judged checkpoint's step,
  under ``verdict/<judge>/``: each advised and baseline run its own conformance ``ca``, and
  each advised run the design's ``delta``, ``interval_low``, ``interval_high``, ``p_value``,
  ``auc``, ``contested`` and ``min_detectable_delta`` (those that exist), and the verdict's
  sentence as text.

No *experiment* summary is written: without one, TensorBoard builds it from the sessions'
hparams and every scalar tag they hold, so the verdict's tags, written later by another
command, are metrics too (an experiment summary would fix the metrics to those it lists).
Nothing here draws a random number or touches training: the training numbers do not change.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from engine.rl.checkpoint import list_checkpoints
from engine.rl.config import TrainConfig
from engine.verdict import Verdict

if TYPE_CHECKING:  # torch loads where a run is trained or judged
    from torch.utils.tensorboard import SummaryWriter

HParam = bool | int | float | str
VERDICT = "verdict"


def config_hparams(config: TrainConfig) -> dict[str, HParam]:
    """The config's fields as hparams: a bool as ``true`` or ``false`` (torch's summary would
    make it the number 1 or 0), a missing value as ``none``, a tuple as its JSON list."""
    out: dict[str, HParam] = {}
    for name, value in dataclasses.asdict(config).items():
        if isinstance(value, bool):
            value = str(value).lower()
        elif value is None or isinstance(value, tuple | list):
            value = "none" if value is None else json.dumps(list(value))
        out[name] = value
    return out


def write_hparams(writer: SummaryWriter, hparams: Mapping[str, HParam]) -> None:
    """Write ``hparams`` as the session start of the run that ``writer`` logs."""
    from torch.utils.tensorboard.summary import hparams as summaries

    _, session_start, _ = summaries(dict(hparams), {})  # type: ignore[no-untyped-call]
    # Into the run's own event file: ``add_hparams`` would open a subfolder, a run of its own.
    # torch types ``file_writer`` as None, but ``SummaryWriter.__init__`` opens it.
    writer.file_writer.add_summary(session_start)  # type: ignore[attr-defined]


def verdict_numbers(result: Verdict) -> dict[str, float]:
    """The design's numbers, without those the verdict has not got (no contested match, one
    seed per arm)."""
    low, high = result.interval or (None, None)
    numbers = {
        "delta": result.delta,
        "interval_low": low,
        "interval_high": high,
        "p_value": result.p_value,
        "auc": result.auc,
        "contested": len(result.matches.contested),
        "min_detectable_delta": result.min_detectable_delta,
    }
    return {name: float(value) for name, value in numbers.items() if value is not None}


def log_verdict(
    result: Verdict, judge: str, advised: Sequence[Path], baseline: Sequence[Path]
) -> None:
    """Write the verdict's numbers into the TensorBoard logs of the runs it scored (module
    doc); the pilot runs only chose the matches and get nothing."""
    design = verdict_numbers(result)
    for i, run in enumerate(advised):
        own = {"ca": result.ca_advised[i]} if result.ca_advised else {}
        _write(Path(run), f"{VERDICT}/{judge}", own | design, result.text)
    for i, run in enumerate(baseline):
        own = {"ca": result.ca_baseline[i]} if result.ca_baseline else {}
        _write(Path(run), f"{VERDICT}/{judge}", own, None)


def _write(run: Path, prefix: str, numbers: Mapping[str, float], text: str | None) -> None:
    """Scalars (and a text) at the step of the run's last checkpoint, the one judged."""
    from torch.utils.tensorboard import SummaryWriter

    step = max(list_checkpoints(run))
    with SummaryWriter(str(run)) as writer:
        for name, value in numbers.items():
            writer.add_scalar(f"{prefix}/{name}", value, step)
        if text is not None:
            writer.add_text(prefix, text, step)
