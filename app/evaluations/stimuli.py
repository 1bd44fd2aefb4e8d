"""An evaluation's stimuli, rendered in the background (issue 41 §1, §3): each slot's run
rolled out deterministically from its checkpoint (:mod:`engine.evaluation.stimuli`), or, for
a policy imported from elsewhere (issue 44), from its one stored ONNX policy in the judges'
limited child process (:mod:`engine.evaluation.imported`); its windows rendered as stills,
and, for a clip evaluation, as clips afterwards. One evaluation may mix both kinds of run.

The evaluation is ``ready`` once the stills are stored: evaluators see stills until
``clips_ready``. Files are named by content hash under the data dir's ``stimuli/`` folder
and served only under a pair's opaque key (:mod:`app.evaluations.evaluator_api`).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import delete, update
from sqlalchemy.orm import Session, sessionmaker

from app.db import writing
from app.evaluations import practice
from app.evaluations.service import slots
from app.jobs.settings import run_dir
from app.models import Evaluation, EvaluationRun, EvaluationStimulus, Run, StudyStatus
from app.runs.imported import imported_of
from app.runs.imported_judge import children_allowed, load_policy
from engine.evaluation.clips import Stimulus
from engine.evaluation.imported import render_imported_clips, render_imported_stimuli
from engine.evaluation.power import AnswersNeeded, answers_needed
from engine.evaluation.simulate import RUN_SD
from engine.evaluation.stimuli import (
    StimulusOptions,
    render_run_clips,
    render_run_stimuli,
)
from engine.render import RenderService
from engine.rl.checkpoint import find_checkpoint

log = logging.getLogger(__name__)

#: The stills-only options every evaluation renders first (its clips use the same windows).
STILLS = StimulusOptions(clips=False)


def stimuli_dir(data_dir: Path) -> Path:
    """Where stimuli are stored (content-addressed, shared by evaluations)."""
    return data_dir / "stimuli"


def prepare_evaluation(
    sessions: sessionmaker[Session],
    *,
    evaluation_id: int,
    renderer: RenderService,
    data_dir: Path,
    runs_dir: Path,
) -> None:
    """Render a ``preparing`` evaluation's stills and its practice states
    (:mod:`app.evaluations.practice`), mark it ``ready``, then render its clips (a clip
    evaluation only) and mark them ready.

    Never raises: a failure is stored on the evaluation (``failed``, ``error``) and logged;
    clips that fail leave the evaluation on stills, with the error stored.
    """
    with sessions() as session:
        evaluation = session.get(Evaluation, evaluation_id)
        if evaluation is None or evaluation.status != StudyStatus.PREPARING:
            return
        env_id, wants_clips = evaluation.env_id, evaluation.stimulus == "clip"
        found = slots(session, evaluation_id=evaluation_id)
        policies = imported_policies(session, found)
    out = stimuli_dir(data_dir)
    try:
        design = design_size(evaluation, found)
        stills = {
            s.slot: _render(s, policies, env_id, runs_dir, out, renderer, clips=False)
            for s in found
        }
        practice.prepare(renderer, data_dir=data_dir, evaluation=evaluation)
        with sessions() as session, writing(session):
            _store(session, evaluation_id, stills, design)
    except Exception as exc:  # any failure must end up on the evaluation, not in a log only
        log.exception("preparing evaluation %d failed", evaluation_id)
        _fail(sessions, evaluation_id, exc, status=StudyStatus.FAILED)
        return
    if wants_clips:
        _add_clips(sessions, evaluation_id, found, policies, env_id, runs_dir, out, renderer)


def imported_policies(session: Session, found: list[EvaluationRun]) -> dict[int, dict[str, Any]]:
    """What each imported run of the slots is (its ``config["imported"]``), by run id; ACV's
    own runs are left out."""
    runs = (session.get(Run, s.run_id) for s in found)
    return {run.id: info for run in runs if run is not None and (info := imported_of(run))}


def _render(
    slot: EvaluationRun,
    policies: dict[int, dict[str, Any]],
    env_id: str,
    runs_dir: Path,
    out: Path,
    renderer: RenderService,
    *,
    clips: bool,
) -> list[Stimulus]:
    """A slot's stimuli: its checkpoint's, or its imported policy's (rolled out in a limited
    child process, as the judges roll it out)."""
    info = policies.get(slot.run_id)
    if info is not None:
        policy = load_policy(runs_dir, info)
        render_policy = render_imported_clips if clips else render_imported_stimuli
        with children_allowed():
            return render_policy(policy, env_id, STILLS, out, service=renderer)
    checkpoint = find_checkpoint(run_dir(runs_dir, slot.run_id), slot.step)
    render = render_run_clips if clips else render_run_stimuli
    return render(checkpoint, env_id, STILLS, out, service=renderer)


def design_size(evaluation: Evaluation, found: list[EvaluationRun]) -> AnswersNeeded:
    """The evaluators the design needs for its target at 80% power: simulated with the
    smaller arm's runs per arm (conservative), round 1's run spread, and seeded by the
    evaluation, so it reads the same every time."""
    k = min(sum(s.advised for s in found), sum(not s.advised for s in found))
    rng = np.random.default_rng([evaluation.seed, 3])
    return answers_needed(
        evaluation.target_win_rate, k, RUN_SD, evaluation.pairs_per_evaluator, rng
    )


def _store(
    session: Session,
    evaluation_id: int,
    stills: dict[int, list[Stimulus]],
    design: AnswersNeeded,
) -> None:
    """The stills' rows and the design's size, then ``ready`` (unless another process got
    there first)."""
    session.execute(
        delete(EvaluationStimulus).where(EvaluationStimulus.evaluation_id == evaluation_id)
    )
    session.add_all(
        EvaluationStimulus(
            evaluation_id=evaluation_id, slot=slot, window=s.window, still_path=s.still
        )
        for slot, found in stills.items()
        for s in found
    )
    session.execute(
        update(Evaluation)
        .where(Evaluation.id == evaluation_id, Evaluation.status == StudyStatus.PREPARING)
        .values(
            status=StudyStatus.READY,
            needed_evaluators=design.evaluators,
            design_power=design.power,
        )
    )


def _add_clips(
    sessions: sessionmaker[Session],
    evaluation_id: int,
    found: list[EvaluationRun],
    policies: dict[int, dict[str, Any]],
    env_id: str,
    runs_dir: Path,
    out: Path,
    renderer: RenderService,
) -> None:
    """Render each slot's clips and store their paths; then ``clips_ready``."""
    try:
        for slot in found:
            clips = _render(slot, policies, env_id, runs_dir, out, renderer, clips=True)
            with sessions() as session, writing(session):
                for s in clips:
                    session.execute(
                        update(EvaluationStimulus)
                        .where(
                            EvaluationStimulus.evaluation_id == evaluation_id,
                            EvaluationStimulus.slot == slot.slot,
                            EvaluationStimulus.window == s.window,
                        )
                        .values(clip_path=s.clip)
                    )
        with sessions() as session, writing(session):
            session.execute(
                update(Evaluation).where(Evaluation.id == evaluation_id).values(clips_ready=True)
            )
    except Exception as exc:  # the evaluation stays on stills; the researcher sees why
        log.exception("rendering the clips of evaluation %d failed", evaluation_id)
        _fail(sessions, evaluation_id, exc, status=None)


def _fail(
    sessions: sessionmaker[Session],
    evaluation_id: int,
    exc: Exception,
    *,
    status: StudyStatus | None,
) -> None:
    error = f"{type(exc).__name__}: {exc}".splitlines()[0]
    values: dict[str, object] = {"error": error}
    where = [Evaluation.id == evaluation_id]
    if status is not None:
        values["status"] = status
        where.append(Evaluation.status == StudyStatus.PREPARING)
    with sessions() as session, writing(session):
        session.execute(update(Evaluation).where(*where).values(values))
