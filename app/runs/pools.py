"""Pooled advice: a run trains on the trees of several finished participants of its study.

The pool is chosen by participant ids (two or more, distinct) or as *all* the study's finished
participants; it is frozen when the run is created as ``runs.advice_pool``
(``{"participant_id", "tree"}`` by increasing id), and the run's ``advice`` is the pooled
verdict (:func:`engine.pooling.pooled_tree`), which every comparison reads as the run's
Human Preference Tree.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.labelling.trees import participant_tree
from app.models import Run
from app.studies.participants import get_participant, list_participants
from engine.errors import InputError
from engine.pooling import check_pool, pooled_tree
from engine.treefile import TreeDocument, tree_to_json

Pool = list[dict[str, Any]]
"""``runs.advice_pool``: ``[{"participant_id": int, "tree": acv.tree/1}, ...]``."""


def pool_ids(
    session: Session,
    *,
    study_id: int,
    participant_ids: Sequence[int] | None,
    all_participants: bool,
) -> list[int] | None:
    """The ids of the pool asked for (increasing), or None when no pool is asked for.

    Raises:
        InputError: both ways of choosing, fewer than two ids, or an id given twice.
        ConflictError: ``all_participants`` while fewer than two have finished.
    """
    if participant_ids is not None and all_participants:
        raise InputError("give participant_ids or all_participants, not both")
    if all_participants:
        return _finished_ids(session, study_id=study_id)
    if participant_ids is None:
        return None
    twice = sorted(i for i, n in Counter(participant_ids).items() if n > 1)
    if twice:
        raise InputError(f"participant_ids names participant {twice[0]} more than once")
    if len(participant_ids) < 2:
        raise InputError(
            f"participant_ids pools at least two participants, got {len(participant_ids)}; "
            "for one, give participant_id"
        )
    return sorted(participant_ids)


def _finished_ids(session: Session, *, study_id: int) -> list[int]:
    done = [
        s.participant.id
        for s in list_participants(session, study_id=study_id)
        if s.progress.finished
    ]
    if len(done) < 2:
        raise ConflictError(
            f"study {study_id} has {len(done)} finished participant(s); pooling needs two or more"
        )
    return sorted(done)


def pool_of(
    session: Session,
    *,
    study_id: int,
    ids: Sequence[int],
    tree_options: dict[str, Any] | None = None,
) -> tuple[Pool, TreeDocument]:
    """The frozen pool of ``ids`` and its pooled verdict tree.

    Raises:
        NotFoundError: an id that is no participant of ``study_id``.
        ConflictError: a participant who has not finished.
        InputError: trees over different brackets (never within one study).
    """
    trees = []
    for pid in ids:
        if get_participant(session, participant_id=pid).study_id != study_id:
            raise NotFoundError(f"participant {pid} is not in study {study_id}")
        trees.append(participant_tree(session, participant_id=pid))
    check_pool(trees)
    pool = [
        {"participant_id": pid, "tree": tree_to_json(t)} for pid, t in zip(ids, trees, strict=True)
    ]
    return pool, pooled_tree(trees, **(tree_options or {}))


def members(run: Run) -> list[int] | None:
    """The participant ids of a pooled run, increasing; None for any other run."""
    return [int(m["participant_id"]) for m in run.advice_pool] if run.advice_pool else None


def pool_label(ids: Sequence[int]) -> str:
    """``3 participants pooled (#1, #2, #4)``."""
    return f"{len(ids)} participants pooled ({', '.join(f'#{i}' for i in ids)})"
