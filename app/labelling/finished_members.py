"""A study's finished participants as runs and surveys read them (issue 43 §3): each one's
Human Preference Tree and, on request, their reliability, in one call.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from sqlalchemy.orm import Session

from app.labelling.participant_quality import ParticipantQuality
from app.labelling.participants import get_participant, list_participants
from app.labelling.quality import quality
from app.labelling.trees import participant_tree
from app.models import Participant
from engine.treefile import TreeDocument


@dataclass(frozen=True)
class FinishedMember:
    """A participant who finished the bracket, with their tree and (when asked) quality.

    Attributes:
        participant: their row.
        tree: their Human Preference Tree (:func:`app.labelling.trees.participant_tree`).
        quality: their label quality, whose ``reliability`` weights a pool; None unless
            asked for.
    """

    participant: Participant
    tree: TreeDocument
    quality: ParticipantQuality | None = None


def finished_members(
    session: Session,
    *,
    study_id: int,
    ids: Sequence[int] | None = None,
    check: Callable[[Participant], None] | None = None,
    reliabilities: bool = False,
) -> list[FinishedMember]:
    """The study's finished participants' trees, and their reliabilities with
    ``reliabilities`` (the study's quality read once).

    Args:
        study_id: the study.
        ids: these participants, in this order; None: every participant of the study who
            finished the bracket, excluded ones too, in invitation order.
        check: called with each participant's row before their tree is read (a caller's own
            refusal: pooling refuses an excluded participant).
        reliabilities: also read each one's :class:`ParticipantQuality`.

    Raises:
        NotFoundError: no such study, or no such participant among ``ids``.
        ConflictError: one of ``ids`` has not finished the bracket.
    """
    found = []
    for person in _people(session, study_id, ids):
        if check is not None:
            check(person)
        found.append((person, participant_tree(session, participant_id=person.id)))
    if not reliabilities:
        return [FinishedMember(person, tree) for person, tree in found]
    by_id = {q.participant.id: q for q in quality(session, study_id=study_id).participants}
    return [FinishedMember(person, tree, by_id.get(person.id)) for person, tree in found]


def _people(session: Session, study_id: int, ids: Sequence[int] | None) -> Iterator[Participant]:
    """The participants asked for, one at a time (each one checked before the next is read)."""
    if ids is None:
        summaries = list_participants(session, study_id=study_id)
        yield from (s.participant for s in summaries if s.progress.finished)
    else:
        yield from (get_participant(session, participant_id=pid) for pid in ids)
