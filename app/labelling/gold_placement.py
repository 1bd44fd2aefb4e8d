"""A participant's copies of the study's gold items (issue 28 §1): where each is placed
among their bracket's matches, on which side, and which one is due now.

Each participant gets a copy of every gold item the study had when they joined (a study's
items apply to people who join after they are added; the items themselves are the
researcher's, :mod:`app.studies.gold`), at a position drawn from the study seed and the
participant: shown once that many bracket matches are decided, always before the last one,
on a seeded side. Their answers are :mod:`app.labelling.gold_answers`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sqlalchemy import Connection, bindparam, select
from sqlalchemy.orm import Session

from app.labelling.sides import a_on_left
from app.models import GoldAnswer, GoldItem, Participant, Study
from app.studies.gold import list_items

#: What an instructed-response item asks.
INSTRUCTED_PROMPT = "Check: choose the picture with the marker."
#: The round number that seeds the sides of gold items (bracket rounds start at 1; 0 is the
#: disagreement pairs').
SIDES_ROUND = -1


@dataclass(frozen=True)
class GoldPair:
    """A gold item due now (:func:`due_gold`), shown before the next match."""

    item_id: int
    kind: str
    a: int
    b: int
    a_left: bool
    answer: int

    @property
    def left(self) -> int:
        return self.a if self.a_left else self.b

    @property
    def marked(self) -> int | None:
        """The candidate shown with the marker (instructed items only)."""
        return self.answer if self.kind == "instructed" else None

    @property
    def prompt(self) -> str | None:
        """What an instructed item asks; ``None`` for a pair, shown like any match."""
        return INSTRUCTED_PROMPT if self.kind == "instructed" else None


#: A participant's first unanswered gold item whose position has come.
_DUE = (
    select(GoldItem.id, GoldItem.kind, GoldItem.a, GoldItem.b, GoldAnswer.a_left, GoldItem.answer)
    .join(GoldItem, GoldItem.id == GoldAnswer.gold_item_id)
    .where(
        GoldAnswer.participant_id == bindparam("pid"),
        GoldAnswer.winner.is_(None),
        GoldAnswer.position <= bindparam("done"),
    )
    .order_by(GoldAnswer.position, GoldAnswer.gold_item_id)
    .limit(1)
)


def due_gold(conn: Connection, *, participant_id: int, done: int) -> GoldPair | None:
    """The participant's gold item to answer now that ``done`` bracket matches are decided
    (one indexed query: the participant's labelling hot path calls it)."""
    row = conn.execute(_DUE, {"pid": participant_id, "done": done}).one_or_none()
    return None if row is None else GoldPair(*row)


def positions(*, n_candidates: int, count: int, seed: int, participant_id: int) -> list[int]:
    """Where a participant's ``count`` gold items go: after how many bracket decisions each
    is shown, drawn from the study seed and the participant (not the researcher), from 1 to
    ``n - 2`` so that each comes after a first decision and before the last one."""
    rng = np.random.default_rng([seed, participant_id, 28])
    low, high = min(1, n_candidates - 2), max(0, n_candidates - 2)
    places = np.arange(low, high + 1)
    drawn = rng.choice(places, size=count, replace=count > len(places))
    return sorted(int(p) for p in drawn)


def stage_gold(session: Session, *, study: Study, people: Sequence[Participant]) -> None:
    """Give each of ``people`` (flushed, so with ids) a copy of the study's gold items, in
    the caller's transaction."""
    items = list_items(session, study_id=study.id)
    for person in people:
        places = positions(
            n_candidates=study.n_candidates,
            count=len(items),
            seed=study.seed,
            participant_id=person.id,
        )
        session.add_all(
            GoldAnswer(
                participant_id=person.id,
                gold_item_id=item.id,
                position=place,
                a_left=a_on_left(
                    seed=study.seed, participant_id=person.id, rnd=SIDES_ROUND, slot=item.id
                ),
            )
            for item, place in zip(items, places, strict=True)
        )
