"""Can this bracket tell? Before any baseline is trained, the matches that can tell whether
an agent used a participant's advice are estimated with R standing in for the no-advice
agent (an agent that goes by R alone): informative matches where R picks the other winner
(:func:`engine.verdict.split_matches`, docs/method.md §2.11). With the smallest Δ that an
experiment of ``seeds`` seeds per arm would detect (α = 0.05, power 0.8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from app.services import participants
from app.services.experiments import DEFAULT_SEEDS
from app.services.trees import participant_tree
from engine.verdict import advice_scores, bracket_pairs, split_matches
from engine.verdict_power import min_detectable_delta

#: Fewer contested matches than this and the page says the bracket cannot tell.
ENOUGH_MATCHES = 8


@dataclass(frozen=True)
class AdvicePower:
    """One finished participant's advice over the study's bracket.

    Attributes:
        participant_id: whose advice.
        n_matches: the bracket's matches.
        contested: informative matches where R picks the other winner (they can tell).
        uninformative: matches where the advice or R has no real preference.
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
    finished = [
        s.participant.id
        for s in participants.list_participants(session, study_id=study_id)
        if s.progress.finished
    ]
    return [_power(session, pid, seeds) for pid in finished]


def _power(session: Session, participant_id: int, seeds: int) -> AdvicePower:
    tree = participant_tree(session, participant_id=participant_id)
    reward = np.array([c.env_reward for c in tree.candidates])
    pairs = bracket_pairs(tree)
    classes = split_matches(advice_scores(tree), reward, pairs)
    n = len(classes.contested)
    return AdvicePower(
        participant_id=participant_id,
        n_matches=len(pairs),
        contested=n,
        uninformative=len(classes.uninformative),
        min_detectable_delta=min_detectable_delta(n, seeds, seeds) if n else None,
        can_tell=n >= ENOUGH_MATCHES,
    )
