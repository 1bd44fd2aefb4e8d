"""A study's practice states (issue 28 §3): sampled, rendered and stored on disk when the
study is prepared, never in the ``candidates`` table.

A study with ``practice_pairs = k > 0`` gets ``2 k`` states that are not its candidates
(:func:`engine.practice.sample_practice_states`), each rendered once plain and once with the
marker of instructed pairs (:func:`engine.render.image.with_marker`). They live in
``<images dir>/practice/<study id>/``: ``state-<i>.jpg``, ``state-<i>-marked.jpg`` and
``states.json`` (the states and the study they belong to), written last, so that a folder
with a ``states.json`` has every image. Files are written atomically (temporary file and
rename): two processes preparing the same study both succeed. Which pairs a participant sees
is :mod:`app.labelling.practice`.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from app.studies.images import SPECS
from engine.practice import sample_practice_states
from engine.render import RenderService
from engine.render.cache import write_atomically
from engine.render.image import with_marker

log = logging.getLogger(__name__)

FORMAT = "acv.practice/1"
MANIFEST = "states.json"


class PracticeOwner(Protocol):
    """What practice states are drawn for and tied to: a study, or an agent evaluation (whose
    evaluators practise on the env's states, never on its agents)."""

    @property
    def id(self) -> int: ...
    @property
    def env_id(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def practice_pairs(self) -> int: ...


@dataclass(frozen=True)
class PracticeStates:
    """A study's practice states as stored: their ``qpos`` and where their pictures are."""

    folder: Path
    qpos: list[list[float]]

    def __len__(self) -> int:
        return len(self.qpos)

    def image(self, index: int, *, marked: bool) -> Path:
        """The picture of state ``index``, with the marker or without."""
        return self.folder / _image_name(index, marked=marked)


def practice_folder(images_dir: Path, study_id: int) -> Path:
    """Where a study's practice states and pictures are stored."""
    return images_dir / "practice" / str(study_id)


def prepare_practice(
    renderer: RenderService,
    *,
    images_dir: Path,
    study: PracticeOwner,
    exclude: Sequence[np.ndarray],
) -> None:
    """Sample, render and store the study's practice states (nothing when it asks none).

    Args:
        renderer: the render service (full-size pictures, as the candidates').
        images_dir: the data dir's images folder.
        study: the study (or evaluation) being prepared.
        exclude: its candidates' ``qpos``: no practice state equals one.
    """
    if study.practice_pairs == 0:
        return
    states = sample_practice_states(
        study.env_id, study.practice_pairs, seed=study.seed, exclude=exclude
    )
    folder = practice_folder(images_dir, study.id)
    pictures = renderer.iter_render(study.env_id, [(s.qpos, s.qvel) for s in states], SPECS["full"])
    for index, picture in enumerate(pictures):
        write_atomically(folder / _image_name(index, marked=False), picture)
        write_atomically(folder / _image_name(index, marked=True), with_marker(picture))
    manifest = {**_owner(study), "states": [{"qpos": s.qpos.tolist()} for s in states]}
    write_atomically(folder / MANIFEST, json.dumps(manifest).encode())


def practice_states(images_dir: Path, study: PracticeOwner) -> PracticeStates | None:
    """The study's stored practice states; None when it asks none, or when they are missing
    or belong to another study (a data dir kept across databases), which is logged."""
    if study.practice_pairs == 0:
        return None
    folder = practice_folder(images_dir, study.id)
    try:
        stored = json.loads((folder / MANIFEST).read_text())
        found = PracticeStates(folder, [s["qpos"] for s in stored["states"]])
        mine = {k: v for k, v in stored.items() if k != "states"} == _owner(study)
    except (OSError, ValueError, KeyError, TypeError):
        found, mine = None, False
    if found is None or not mine or len(found) != 2 * study.practice_pairs:
        log.warning("study %d has no practice states in %s: practice is skipped", study.id, folder)
        return None
    return found


def _owner(study: PracticeOwner) -> dict[str, Any]:
    """What ties stored practice states to their study."""
    return {
        "format": FORMAT,
        "study_id": study.id,
        "env_id": study.env_id,
        "seed": study.seed,
        "pairs": study.practice_pairs,
    }


def _image_name(index: int, *, marked: bool) -> str:
    return f"state-{index}{'-marked' if marked else ''}.{SPECS['full'].fmt}"
