"""Can this bracket tell? The matches that can tell whether an agent used a participant's
advice are estimated with a stand-in for the no-advice agent: the study's baseline (its
return from each candidate, stored for studies that ask disagreement pairs) where there is
one, else R (an agent that goes by R alone). They are the informative matches where the
stand-in picks the other winner (:func:`engine.verdict.split_matches`, docs/method.md
§2.11), over the bracket and the participant's answered disagreement pairs. With the smallest
Δ that an experiment of ``seeds`` seeds per arm would detect (α = 0.05, power 0.8).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.labelling import disagreement
from app.labelling.finished_members import FinishedMember, finished_members
from app.models import Candidate
from app.runs.experiments import DEFAULT_SEEDS
from engine.verdict import advice_scores, bracket_pairs, split_matches
from engine.verdict_power import min_detectable_delta

#: Fewer contested matches than this and the page says the bracket cannot tell.
ENOUGH_MATCHES = 8


@dataclass(frozen=True)
class AdvicePower:
    """One finished participant's advice over the study's bracket.

    Attributes:
        participant_id: whose advice.
        n_matches: the bracket's matches and the answered disagreement pairs.
        contested: informative matches where the stand-in (baseline or R) picks the other
            winner (they can tell).
        uninformative: matches where the advice or the stand-in has no real preference.
        min_detectable_delta: the smallest Δ an experiment of ``seeds`` seeds per arm
            detects on ``contested`` matches (None: none, too few matches or seeds).
        can_tell: at least :data:`ENOUGH_MATCHES` contested matches.
    """

    participant_id: int
    n_matches: int
    contested: int
    uninformative: int
    min_detectable_delta: float | None
    can_tell: bool


def study_power(
    session: Session, *, study_id: int, seeds: int = DEFAULT_SEEDS
) -> list[AdvicePower]:
    """:class:`AdvicePower` of every finished participant of the study, in invitation order."""
    finished = finished_members(session, study_id=study_id)
    baseline = session.scalars(
        select(Candidate.baseline_return)
        .where(Candidate.study_id == study_id)
        .order_by(Candidate.id)
    ).all()
    known = baseline and all(r is not None for r in baseline)
    return [_power(session, m, seeds, baseline if known else None) for m in finished]


def _power(
    session: Session,
    member: FinishedMember,
    seeds: int,
    baseline: Sequence[float | None] | None,
) -> AdvicePower:
    tree, participant_id = member.tree, member.participant.id
    stand_in = [c.env_reward for c in tree.candidates] if baseline is None else baseline
    pairs = bracket_pairs(tree) + disagreement.answered(session, participant_id=participant_id)
    classes = split_matches(advice_scores(tree), np.array(stand_in, dtype=float), pairs)
    n = len(classes.contested)
    return AdvicePower(
        participant_id=participant_id,
        n_matches=len(pairs),
        contested=n,
        uninformative=len(classes.uninformative),
        min_detectable_delta=min_detectable_delta(n, seeds, seeds) if n else None,
        can_tell=n >= ENOUGH_MATCHES,
    )
