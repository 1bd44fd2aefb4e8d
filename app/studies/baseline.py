"""The no-advice baseline that ``informative`` candidate sampling rolls out, and that picks
disagreement pairs.

``informative`` sampling (:mod:`engine.informative`) follows a trained no-advice baseline:
the latest ``ppo`` run on the study's env (any study's) that succeeded before the study was
created (:func:`baseline_run`). ``ppo`` trains on R alone, whether or not it names advice to
be compared with. Runs that finish later are ignored, so preparing the study again (after a
restart) picks the same run; creating the study fails with :class:`InputError` when there is
none. A study that asks disagreement pairs (:mod:`engine.disagreement`) needs the same
baseline: its return from each candidate is stored with the candidate
(:func:`baseline_returns`).
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.models import Run, RunStatus, Study, utcnow
from engine.candidates import BASELINE_MODES, Candidate, Policy
from engine.errors import InputError


def no_baseline_message(env_id: str, *, needs: str = "informative sampling needs") -> str:
    """Why a study whose settings ``needs`` (say so) a baseline cannot be made on ``env_id``."""
    return f"{needs} a finished no-advice ppo run on {env_id}; train one first"


def needs_baseline(*, sampling: str, disagreement_pairs: int) -> str | None:
    """Which of a study's settings need a no-advice baseline run, as the subject and verb of
    :func:`no_baseline_message` (None: none does)."""
    if sampling in BASELINE_MODES:
        return f"{sampling} sampling needs"
    return "disagreement pairs need" if disagreement_pairs else None


def baseline_run(session: Session, *, env_id: str, before: datetime | None = None) -> Run | None:
    """The no-advice baseline of ``informative`` sampling: the latest ``ppo`` run on ``env_id``
    (of any study) that succeeded, finished at ``before`` or earlier (now when None)."""
    return session.scalars(
        select(Run)
        .join(Study, Run.study_id == Study.id)
        .where(
            Study.env_id == env_id,
            Run.algo == "ppo",
            Run.status == RunStatus.SUCCEEDED,
            Run.finished_at <= (before or utcnow()),
        )
        .order_by(Run.finished_at.desc(), Run.id.desc())
        .limit(1)
    ).first()


def baseline_policy(run_id: int, runs_dir: Path) -> Policy:
    """The deterministic policy of a baseline run's last checkpoint (loads torch)."""
    from app.jobs.settings import run_dir
    from engine.rl.checkpoint import find_checkpoint
    from engine.rl.trained import deterministic_policy, load_agent

    return deterministic_policy(load_agent(find_checkpoint(run_dir(runs_dir, run_id))))


def study_baseline_id(session: Session, study: Study) -> int | None:
    """The baseline run of a study that needs one (None when it does not, or none found)."""
    if not needs_baseline(sampling=study.sampling, disagreement_pairs=study.disagreement_pairs):
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


def baseline_returns(
    study: Study,
    baseline_id: int | None,
    candidates: list[Candidate],
    runs_dir: Path,
    policy: Policy | None,
) -> list[float] | None:
    """The baseline's return from each candidate, for a study that asks disagreement pairs
    (None for another): the ``informative`` estimate where sampling made one, else the return
    judge's rollouts of the baseline's policy (:func:`engine.rl.returns.state_returns`).

    Raises:
        InputError: the study has no baseline run.
    """
    if not study.disagreement_pairs:
        return None
    estimates = [c.seed_score for c in candidates]
    if all(e is not None for e in estimates):
        return [float(e) for e in estimates if e is not None]
    if baseline_id is None:
        raise InputError(no_baseline_message(study.env_id, needs="disagreement pairs need"))
    from engine.rl.returns import ReturnOptions, state_returns

    returns = state_returns(
        policy or baseline_policy(baseline_id, runs_dir),
        study.env_id,
        np.stack([c.qpos for c in candidates]),
        np.stack([c.qvel for c in candidates]),
        ReturnOptions(seed=study.seed % 2**31),
    )
    return [float(r) for r in returns.mean(axis=1)]
