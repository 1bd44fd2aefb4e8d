"""A run's TensorBoard logs as TensorBoard reads them: every event file of the run folder,
through TensorBoard's own loader and its hparams plugin's parser."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from google.protobuf.json_format import MessageToDict
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
from tensorboard.plugins.hparams import metadata


def events(run: Path) -> EventAccumulator:
    """Everything the run folder's event files hold (no sampling: every scalar and text)."""
    loaded = EventAccumulator(str(run), size_guidance={"scalars": 0, "tensors": 0})
    loaded.Reload()
    return loaded


def hparams(run: Path) -> dict[str, Any]:
    """The hyper-parameters of the run's session, as the HPARAMS dashboard lists them."""
    content = events(run).PluginTagToContent(metadata.PLUGIN_NAME)
    start = metadata.parse_session_start_info_plugin_data(content[metadata.SESSION_START_INFO_TAG])
    return {name: value for name, value in MessageToDict(start)["hparams"].items()}


def last_scalars(run: Path, prefix: str) -> dict[str, tuple[int, float]]:
    """Each scalar tag under ``prefix`` (without it) -> its last ``(step, value)``."""
    loaded = events(run)
    return {
        tag.removeprefix(prefix): (loaded.Scalars(tag)[-1].step, loaded.Scalars(tag)[-1].value)
        for tag in loaded.Tags()["scalars"]
        if tag.startswith(prefix)
    }
