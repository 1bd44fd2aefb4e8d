"""The no-advice baseline that ``informative`` candidate sampling rolls out.

``informative`` sampling (:mod:`engine.informative`) follows a trained no-advice baseline:
the latest ``ppo`` run on the study's env (any study's) that succeeded before the study was
created (:func:`baseline_run`). ``ppo`` trains on R alone, whether or not it names advice to
be compared with. Runs that finish later are ignored, so preparing the study again (after a
restart) picks the same run; creating the study fails with :class:`InputError` when there is
none.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.models import Run, RunStatus, Study, utcnow
from engine.candidates import BASELINE_MODES, Policy
from engine.errors import InputError


def no_baseline_message(env_id: str) -> str:
    """Why an ``informative`` study cannot be sampled on ``env_id``."""
    return f"informative sampling needs a finished no-advice ppo run on {env_id}; train one first"


def baseline_run(session: Session, *, env_id: str, before: datetime | None = None) -> Run | None:
    """The no-advice baseline of ``informative`` sampling: the latest ``ppo`` run on ``env_id``
    (of any study) that succeeded, finished at ``before`` or earlier (now when None)."""
    return session.scalars(
        select(Run)
        .join(Study, Run.study_id == Study.id)
        .where(
            Study.env_id == env_id,
            Run.algo == "ppo",
            Run.status == RunStatus.SUCCEEDED.value,
            Run.finished_at <= (before or utcnow()),
        )
        .order_by(Run.finished_at.desc(), Run.id.desc())
        .limit(1)
    ).first()


def baseline_policy(run_id: int, runs_dir: Path) -> Policy:
    """The deterministic policy of a baseline run's last checkpoint (loads torch)."""
    from app.jobs.execute import run_dir
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.trained import deterministic_policy, load_agent

    return deterministic_policy(load_agent(find_checkpoint(run_dir(runs_dir, run_id))))


def study_baseline_id(session: Session, study: Study) -> int | None:
    """The baseline run of an ``informative`` study (None for another mode, or none found)."""
    if study.sampling not in BASELINE_MODES:
        return None
    run = baseline_run(session, env_id=study.env_id, before=study.created_at)
    return None if run is None else run.id


def study_policy(study: Study, baseline_id: int | None, runs_dir: Path) -> Policy | None:
    """What the study's candidate rollouts follow: its baseline's policy for ``informative``
    sampling, random actions (None) otherwise.

    Raises:
        InputError: an ``informative`` study without a baseline run.
    """
    if study.sampling not in BASELINE_MODES:
        return None
    if baseline_id is None:
        raise InputError(no_baseline_message(study.env_id))
    return baseline_policy(baseline_id, runs_dir)
