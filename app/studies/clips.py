"""Clips in ordinary studies (issue 41 §3): opted in by the researcher, rendered in the
background once the study is ready with stills, so that its readiness time does not change.

A candidate's clip starts at its state and rolls forward, ``clip_s`` seconds (2 s at about
15 fps, :class:`~engine.evaluation.stimuli.StimulusOptions`), under the deterministic policy
that sampled it (:func:`engine.evaluation.stimuli.render_candidate_clip`):

- ``informative`` sampling followed the study's no-advice baseline: its clips follow that run's
  deterministic policy (``clip_policy`` "baseline run <id>");
- ``uniform`` and ``diverse`` sampling took uniform random actions: their clips take uniform
  random actions drawn from the clip's seed alone (``clip_policy`` "random actions",
  :func:`engine.candidates.random_actions`), the same for every candidate of every study.

``clip_seed`` is the reset seed before the state is restored,
:data:`~engine.evaluation.stimuli.STIMULUS_SEED0`, which also seeds the random actions.
Clips are content-addressed under the data dir's ``stimuli/`` folder (as evaluations' are);
``clip_path`` is relative to the data dir, like the candidates' images, and is served only
where they are. A failure leaves the study on stills, with the error stored and logged.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from app.db import writing
from app.models import Candidate, Study, StudyStatus
from app.studies.baseline import baseline_policy, no_baseline_message, study_baseline_id
from engine.candidates import BASELINE_MODES, Policy, random_actions
from engine.errors import InputError
from engine.evaluation.stimuli import STIMULUS_SEED0, StimulusOptions, render_candidate_clip
from engine.render import RenderService

log = logging.getLogger(__name__)

#: The data dir's folder of stimuli (clips), shared with agent evaluations.
STIMULI = "stimuli"
#: What each clip shows: 2 s at about 15 fps, the candidates' camera and size.
CLIP_OPTIONS = StimulusOptions(windows=1, clips=True)

#: The researcher's choice, as the form and the CLI say it.
CLIPS_WARNING = (
    "A clip shows motion, but F, the advice reward, rewards the posture alone: the tree is "
    "built from the states, not from what happens after them."
)


def clip_policy(
    study: Study, baseline_id: int | None, runs_dir: Path
) -> tuple[str, Callable[[], Policy]]:
    """What rolls the study's candidates forward in their clips: its name, as stored in
    ``clip_policy``, and a maker of a fresh policy (random actions restart at the seed).

    Raises:
        InputError: an ``informative`` study without a baseline run.
    """
    if study.sampling in BASELINE_MODES:
        if baseline_id is None:
            raise InputError(no_baseline_message(study.env_id))
        policy = baseline_policy(baseline_id, runs_dir)
        return f"baseline run {baseline_id}", lambda: policy
    env_id = study.env_id
    return "random actions", lambda: random_actions(env_id, STIMULUS_SEED0)


def add_clips(
    sessions: sessionmaker[Session],
    *,
    study_id: int,
    renderer: RenderService,
    data_dir: Path,
    runs_dir: Path,
) -> None:
    """Render the clip of each candidate of a ready clips study that has none yet, store it
    with its policy and seed, then set ``clips_ready``. Does nothing for another study.

    Never raises: a failure is logged and stored in the study's ``error``; it stays ready,
    on stills."""
    with sessions() as session:
        study = session.get(Study, study_id)
        if study is None or not (study.clips and study.status == StudyStatus.READY):
            return
        if study.clips_ready:
            return
        baseline = study_baseline_id(session, study)
        todo = [
            (c.id, np.asarray(c.qpos, dtype=np.float64), np.asarray(c.qvel, dtype=np.float64))
            for c in session.scalars(
                select(Candidate)
                .where(Candidate.study_id == study_id, Candidate.clip_path.is_(None))
                .order_by(Candidate.id)
            )
        ]
    try:
        name, make_policy = clip_policy(study, baseline, runs_dir)
        out = data_dir / STIMULI
        for cid, qpos, qvel in todo:
            clip = render_candidate_clip(
                make_policy(), study.env_id, qpos, qvel, CLIP_OPTIONS, out, service=renderer
            )
            path = f"{STIMULI}/{clip.clip}"
            with sessions() as session, writing(session):
                session.execute(
                    update(Candidate)
                    .where(Candidate.study_id == study_id, Candidate.id == cid)
                    .values(clip_path=path, clip_policy=name, clip_seed=STIMULUS_SEED0)
                )
        with sessions() as session, writing(session):
            session.execute(update(Study).where(Study.id == study_id).values(clips_ready=True))
    except Exception as exc:  # the study stays on stills; the researcher sees why
        log.exception("rendering the clips of study %d failed", study_id)
        error = f"clips: {type(exc).__name__}: {exc}".splitlines()[0]
        with sessions() as session, writing(session):
            session.execute(update(Study).where(Study.id == study_id).values(error=error))


def clips_state(study: Study) -> str | None:
    """What the study page says of its clips: None (no clips), ``rendering``, ``ready`` or
    ``failed`` (its ``error`` says why)."""
    if not study.clips:
        return None
    if study.clips_ready:
        return "ready"
    return "failed" if study.error and study.status == StudyStatus.READY else "rendering"


def pending_clip_ids(session: Session) -> list[int]:
    """Ready clips studies whose clips are neither ready nor failed (e.g. after a restart)."""
    return list(
        session.scalars(
            select(Study.id).where(
                Study.clips.is_(True),
                Study.clips_ready.is_(False),
                Study.status == StudyStatus.READY,
                Study.error.is_(None),
            )
        )
    )
