"""The runs experiments share (issue 45 §4): one ``ppo`` run per study, config and seed
that names advice is every experiment's baseline or pilot there.

The shared run carries the digest of its config (``runs.config_digest``), and a partial
unique index on ``(study_id, config_digest, seed)`` lets the database keep one: a run is
stored with ``INSERT ... ON CONFLICT DO NOTHING``, and when that stores nothing, the run
already there is the one (for an experiment), or the new run is stored without the digest
(a plain ``POST /api/runs``, which always trains). Two identical experiments posted at once
therefore share their baseline and pilot runs, never a check that both pass before either
inserts. A failed or cancelled shared run gives its place up to the next one asked for.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from app.core.atomic import insert_or_nothing
from app.core.errors import ConflictError
from app.db import writing
from app.models import Run, RunStatus

#: A shared run in one of these is replaced by the next one asked for.
GIVEN_UP: tuple[RunStatus, ...] = (RunStatus.FAILED, RunStatus.CANCELLED)


def config_digest(config: dict[str, Any]) -> str:
    """The SHA-256 (hex) of a run's stored config, keys sorted: equal configs, equal
    digests."""
    canonical = json.dumps(config, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def shareable(values: dict[str, Any]) -> bool:
    """Whether a run of these column values may be shared: ``ppo`` that names advice (only
    runs that name advice have their checkpoints judged, :mod:`app.jobs.execute`)."""
    return values["algo"] == "ppo" and values["advice"] is not None


def store(session: Session, values: dict[str, Any], *, reuse: bool) -> Run:
    """Store a shareable run of column ``values``, in one write transaction.

    Args:
        reuse: return the shared run of the same study, config and seed when there is one
            (an experiment's baseline or pilot); otherwise store a new run, which becomes
            the shared one if there is none.

    Raises:
        ConflictError: the shared run changed between the insert and its look-up (its run
            failed and another took its place at that moment); trying again settles it.
    """
    digest = config_digest(values["config"])
    key = (
        Run.study_id == values["study_id"],
        Run.config_digest == digest,
        Run.seed == values["seed"],
    )
    with writing(session):
        given_up = update(Run).where(*key, Run.status.in_(GIVEN_UP))
        session.execute(given_up.values(config_digest=None))
        claimed = insert_or_nothing(
            session,
            Run,
            index_elements=[Run.study_id, Run.config_digest, Run.seed],
            index_where=Run.config_digest.is_not(None),
        )
        run_id = session.scalar(claimed.values(**values, config_digest=digest).returning(Run.id))
        if run_id is None and reuse:
            run_id = session.scalar(select(Run.id).where(*key))
            if run_id is None:
                raise ConflictError("the shared run changed meanwhile; try again")
        elif run_id is None:
            run = Run(**values)
            session.add(run)
            session.flush()
            run_id = run.id
    return session.get_one(Run, run_id)
