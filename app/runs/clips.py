"""A run's clip for researchers (issue 41 §3): what the run's latest checkpoint does, as the
animated WebP of its first stimulus window, rendered once in the background.

The clip is window 0 of :func:`engine.evaluation.stimuli.render_run_clips` under the
options the caller passes (the evaluations' defaults): episode ``STIMULUS_SEED0`` and the
first offset drawn from the options' seed, which are the same whether one window or four
are chosen, so it is the very file an evaluation of the run stores for its window 0. Only
that one window is rolled out and rendered here.

Files are content-addressed under the caller's stimuli folder; a small index
``run_clips/<key>.json`` names the clip and still of each checkpoint's content (``key``
hashes the checkpoint's bytes, the env and the options), so a clip is found again without
rendering, and a run id never names a file.
"""

from __future__ import annotations

import hashlib
import json
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.jobs.settings import run_dir
from app.runs import run_state
from app.runs import service as runs
from app.studies import service as studies
from engine.errors import InputError
from engine.evaluation.stimuli import StimulusOptions, render_run_clips
from engine.render import RenderService
from engine.render.cache import write_atomically
from engine.rl.checkpoint import find_checkpoint
from engine.rl.judge_cache import file_digest

log = logging.getLogger(__name__)

#: Part of the index key: bump it when what a run's clip shows changes.
CLIP_VERSION = 1
#: The window shown (the first).
WINDOW = 0
Part = Literal["clip", "still"]


@dataclass(frozen=True)
class ClipSource:
    """What a run's clip is made from.

    Attributes:
        run_id: the run.
        step: its latest saved checkpoint's timesteps.
        checkpoint: that checkpoint's file.
        env_id: the run's env.
        key: the index key (checkpoint content, env, options).
    """

    run_id: int
    step: int
    checkpoint: Path
    env_id: str
    key: str


def clip_source(
    session: Session, *, run_id: int, runs_dir: Path, options: StimulusOptions
) -> ClipSource:
    """The run's latest checkpoint, its env and its clip's key.

    Raises:
        NotFoundError: no such run, or it saved no checkpoint (or its file is gone).
    """
    run = runs.get_run(session, run_id=run_id)
    steps = run_state.checkpoint_steps(session, run_id=run_id)
    if not steps:
        raise NotFoundError(f"run {run_id} has saved no checkpoint yet")
    try:
        checkpoint = find_checkpoint(run_dir(runs_dir, run_id), steps[-1])
    except InputError:
        raise NotFoundError(f"the checkpoint of run {run_id} at {steps[-1]} is gone") from None
    env_id = studies.get_study(session, study_id=run.study_id).env_id
    text = f"acv-run-clip/{CLIP_VERSION}|{file_digest(checkpoint)}|{env_id}|{_one(options)!r}"
    key = hashlib.blake2b(text.encode(), digest_size=20).hexdigest()
    return ClipSource(run_id, steps[-1], checkpoint, env_id, key)


def _one(options: StimulusOptions) -> StimulusOptions:
    """The options with one window and clips: window 0 is the same as with more."""
    return replace(options, windows=1, clips=True)


def _index(out_dir: Path, key: str) -> Path:
    return out_dir / "run_clips" / f"{key}.json"


def stored(source: ClipSource, out_dir: Path, part: Part = "clip") -> Path | None:
    """The stored file of the run's clip (or its still), None until it is rendered.

    Raises:
        ConflictError: rendering it failed (the error is kept in the index).
    """
    index = _index(out_dir, source.key)
    if not index.is_file():
        return None
    record = json.loads(index.read_text())
    if "error" in record:
        raise ConflictError(f"rendering the clip of run {source.run_id} failed: {record['error']}")
    found = out_dir / record[part]
    return found if found.is_file() else None


class ClipQueue:
    """The clips being rendered, so none renders twice at once."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rendering: set[str] = set()

    def claim(self, key: str) -> bool:
        """Whether the caller may render ``key`` (False: it is being rendered already)."""
        with self._lock:
            if key in self._rendering:
                return False
            self._rendering.add(key)
            return True

    def release(self, key: str) -> None:
        with self._lock:
            self._rendering.discard(key)

    def busy(self, key: str) -> bool:
        with self._lock:
            return key in self._rendering


#: The process's clips being rendered.
QUEUE = ClipQueue()


def render_clip(
    source: ClipSource,
    *,
    options: StimulusOptions,
    out_dir: Path,
    renderer: RenderService,
    queue: ClipQueue = QUEUE,
) -> None:
    """Render the run's clip and index it, then release its claim in ``queue``; a failure
    is indexed (so it is answered, not rendered again and again) and logged, never raised.
    Meant for the background worker, after :meth:`ClipQueue.claim`."""
    try:
        found = render_run_clips(
            source.checkpoint, source.env_id, _one(options), out_dir, service=renderer
        )[WINDOW]
        record = {"clip": found.clip, "still": found.still}
    except Exception as exc:  # the researcher reads why, instead of waiting forever
        log.exception("rendering the clip of run %d failed", source.run_id)
        record = {"error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    try:
        write_atomically(_index(out_dir, source.key), json.dumps(record).encode())
    finally:
        queue.release(source.key)


#: Queues ``job(key)`` in the background (:meth:`app.runtime.Runtime.submit`).
Submit = Callable[[Callable[[int], None], int], object]


def stored_or_queued(
    source: ClipSource,
    out_dir: Path,
    part: Part,
    *,
    options: StimulusOptions,
    renderer: RenderService,
    submit: Submit,
) -> Path | None:
    """The stored file of ``part``, or ``None`` after queueing the clip's rendering (once
    per clip at a time: :data:`QUEUE`)."""
    found = stored(source, out_dir, part)
    if found is not None or not QUEUE.claim(source.key):
        return found

    def job(_: int) -> None:
        render_clip(source, options=options, out_dir=out_dir, renderer=renderer)

    try:
        submit(job, source.run_id)
    except Exception:  # the worker is shut down: let the next request claim it again
        QUEUE.release(source.key)
        raise
    return None
