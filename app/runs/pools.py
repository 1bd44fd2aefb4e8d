"""Pooled advice: a run trains on the trees of several finished participants of its study.

The pool is chosen by participant ids (two or more, distinct) or as *all* the study's finished
participants; participants the researcher excluded (``participants.excluded``) are never
pooled. It is frozen when the run is created as ``runs.advice_pool``
(``{"participant_id", "tree"}`` by increasing id), and the run's ``advice`` is the pooled
verdict (:func:`engine.pooling.pooled_tree`), which every comparison reads as the run's
Human Preference Tree.

The pool's trees are averaged by the plain mean, or weighted by each participant's
reliability (:func:`reliability_weights`, issue 28 §2): the weights are the run's
``config.pool_weights`` (what F trains with), and each pooled participant weighted below the
pool's highest weight has a ``why`` in their ``advice_pool`` entry.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from app.core.errors import ConflictError, NotFoundError
from app.labelling.finished_members import FinishedMember, finished_members
from app.labelling.participant_quality import ParticipantQuality
from app.labelling.participants import list_participants
from app.models import Participant, Run
from app.runs.spec import PoolWeighting
from engine.errors import InputError
from engine.pooling import check_pool, pooled_tree
from engine.treefile import TreeDocument, tree_to_json

Pool = list[dict[str, Any]]
"""``runs.advice_pool``: ``[{"participant_id": int, "tree": acv.tree/1, "why"?: str}, ...]``
(``why``: reliability weighting only, for a participant it weighted down)."""


@dataclass(frozen=True)
class PoolWeight:
    """A pooled participant's weight, and why the pool weighted them down (None: it did not).

    Attributes:
        participant_id: the participant.
        weight: their reliability (:attr:`ParticipantQuality.reliability`), in [0, 1].
        why: for a weight below the pool's highest, what their known-answer checks showed.
    """

    participant_id: int
    weight: float
    why: str | None = None


@dataclass(frozen=True)
class Pooled:
    """A pool frozen for a run.

    Attributes:
        members: ``runs.advice_pool``.
        weights: one per member, in their order (None: the plain mean).
        verdict: the pooled verdict, weighted like F.
    """

    members: Pool
    weights: tuple[float, ...] | None
    verdict: TreeDocument


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
        if s.progress.finished and not s.participant.excluded
    ]
    if len(done) < 2:
        raise ConflictError(
            f"study {study_id} has {len(done)} finished participant(s) not excluded from "
            "pooling; pooling needs two or more"
        )
    return sorted(done)


def pool_of(
    session: Session,
    *,
    study_id: int,
    ids: Sequence[int],
    tree_options: dict[str, Any] | None = None,
    weighted: bool = False,
) -> Pooled:
    """The frozen pool of ``ids``, weighted by reliability when ``weighted``, and its pooled
    verdict tree (with F's ``tree_options``).

    Raises:
        NotFoundError: an id that is no participant of ``study_id``.
        ConflictError: a participant who has not finished or is excluded, or (``weighted``)
            every reliability 0.
        InputError: trees over different brackets (never within one study).
    """
    members = finished_members(
        session,
        study_id=study_id,
        ids=ids,
        check=lambda person: _check_poolable(person, study_id),
        reliabilities=weighted,
    )
    trees = [m.tree for m in members]
    check_pool(trees)
    found = reliability_weights(members, study_id=study_id) if weighted else None
    whys = {w.participant_id: w.why for w in found or () if w.why is not None}
    pool: Pool = [
        {"participant_id": pid, "tree": tree_to_json(t)}
        | ({"why": whys[pid]} if pid in whys else {})
        for pid, t in zip(ids, trees, strict=True)
    ]
    weights = None if found is None else tuple(w.weight for w in found)
    return Pooled(pool, weights, pooled_tree(trees, **(tree_options or {}), weights=weights))


def _check_poolable(person: Participant, study_id: int) -> None:
    if person.study_id != study_id:
        raise NotFoundError(f"participant {person.id} is not in study {study_id}")
    if person.excluded:
        reason = f" ({person.exclusion_reason})" if person.exclusion_reason else ""
        raise ConflictError(
            f"participant {person.id} is excluded from pooling{reason}; leave them out"
        )


def reliability_weights(members: Sequence[FinishedMember], *, study_id: int) -> list[PoolWeight]:
    """Each of ``members`` (read with their reliabilities:
    :func:`app.labelling.finished_members.finished_members`) weighted by their reliability,
    with why for each one below the pool's highest weight: a weighted mean only compares
    weights, so the most reliable count fully and the others are weighted down.

    Raises:
        NotFoundError: a member who is no participant of ``study_id``.
        ConflictError: every reliability is 0 (nothing to weight by).
    """
    by_id = {m.participant.id: m.quality for m in members if m.quality is not None}
    ids = [m.participant.id for m in members]
    stranger = next((pid for pid in ids if pid not in by_id), None)
    if stranger is not None:
        raise NotFoundError(f"participant {stranger} is not in study {study_id}")
    weights = [by_id[pid].reliability for pid in ids]
    if max(weights, default=0.0) <= 0:
        raise ConflictError(
            'every pooled participant has reliability 0; use the plain mean (pool_weighting "mean")'
        )
    top = max(weights)
    return [
        PoolWeight(pid, w, None if w >= top else why_weighted_down(by_id[pid]))
        for pid, w in zip(ids, weights, strict=True)
    ]


def why_weighted_down(person: ParticipantQuality) -> str:
    """What a participant's known-answer checks showed, for people: ``reliability 0.08 from 1
    known-answer check: failed the consistency check``."""
    checks, head = person.checks, f"reliability {person.reliability:.2f}"
    if checks.asked == 0:
        return f"{head}: no known-answer check answered yet, so the prior's cautious weight"
    failed = []
    if wrong := checks.consistency_asked - checks.consistent:
        failed.append(
            "failed the consistency check"
            if checks.consistency_asked == 1
            else f"failed {wrong} of {checks.consistency_asked} consistency checks"
        )
    if wrong := checks.gold_asked - checks.gold_right:
        failed.append(f"answered {wrong} of {checks.gold_asked} gold items wrong")
    detail = "; ".join(failed) or "passed them all, but fewer checks give a more cautious weight"
    plural = "" if checks.asked == 1 else "s"
    return f"{head} from {checks.asked} known-answer check{plural}: {detail}"


def members(run: Run) -> list[int] | None:
    """The participant ids of a pooled run, increasing; None for any other run."""
    return [int(m["participant_id"]) for m in run.advice_pool] if run.advice_pool else None


def same_pool(one: Run, other: Run) -> bool:
    """Whether two runs pool the same participants with the same weights (the same advice);
    True for two runs on no pool."""
    same_weights = one.config.get("pool_weights") == other.config.get("pool_weights")
    return members(one) == members(other) and same_weights


def weighting_of(run: Run) -> PoolWeighting | None:
    """How a pooled run averages its trees; None for any other run."""
    if not run.advice_pool:
        return None
    return "mean" if run.config.get("pool_weights") is None else "reliability"


def weights_of(run: Run) -> list[PoolWeight] | None:
    """The weights of a run on a reliability-weighted pool, with why for those weighted down;
    None for the plain mean or any other run."""
    weights = run.config.get("pool_weights")
    if not run.advice_pool or weights is None:
        return None
    return [
        PoolWeight(int(m["participant_id"]), float(w), m.get("why"))
        for m, w in zip(run.advice_pool, weights, strict=True)
    ]


def pool_label(ids: Sequence[int], *, weighted: bool = False) -> str:
    """``3 participants pooled (#1, #2, #4)``; ``... pooled by reliability (...)`` when
    weighted."""
    how = " by reliability" if weighted else ""
    return f"{len(ids)} participants pooled{how} ({', '.join(f'#{i}' for i in ids)})"
