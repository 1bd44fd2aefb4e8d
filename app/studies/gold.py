"""Gold items (issue 28 §1): pairs with an objective answer that the researcher defines for
a study, shown among the bracket's matches at seeded positions, never part of the bracket or
the tree.

Two kinds:

- ``pair``: two of the study's candidates, one of which the researcher says is right (a
  fallen and an upright posture in a study about standing, say). Shown like any match.
- ``instructed``: an instructed-response item, "choose the picture with the marker": the
  ``answer`` candidate is shown with a marker drawn on it.

Here are the study's items (listed, added, removed). Each participant's copies, where they
are placed and their answers, are the participant's journey:
:mod:`app.labelling.gold_placement` and :mod:`app.labelling.gold_answers`.
"""

from __future__ import annotations

from typing import Any, Literal, cast

from sqlalchemy import CursorResult, delete, func, select
from sqlalchemy.orm import Session

from app.core import atomic
from app.core.errors import ConflictError, NotFoundError
from app.db import writing
from app.models import Candidate, GoldAnswer, GoldItem, Study
from app.studies.service import get_ready_study, get_study
from engine.errors import InputError

GoldKind = Literal["pair", "instructed"]
GOLD_KINDS: tuple[GoldKind, ...] = ("pair", "instructed")
#: Most gold items a study may have: each one is a decision that is not a preference.
MAX_GOLD_ITEMS = 10


def list_items(session: Session, *, study_id: int) -> list[GoldItem]:
    """The study's gold items, oldest first.

    Raises:
        NotFoundError: no such study.
    """
    get_study(session, study_id=study_id)
    return list(
        session.scalars(
            select(GoldItem).where(GoldItem.study_id == study_id).order_by(GoldItem.id)
        ).all()
    )


def add_item(
    session: Session, *, study_id: int, kind: GoldKind, a: int, b: int, answer: int
) -> GoldItem:
    """Add a gold item to a ready study; participants who join from now on get it.

    Raises:
        NotFoundError, ConflictError: no such study, or it is not ready.
        InputError: an unknown kind, ``a == b``, a candidate that is not the study's, an
            answer that is neither ``a`` nor ``b``, or too many items.
    """
    study = get_ready_study(session, study_id=study_id)
    _check_item(session, study, kind, a, b, answer)
    item = GoldItem(study_id=study_id, kind=kind, a=a, b=b, answer=answer)
    with writing(session):  # counted with the item: concurrent adds never pass the limit
        if not atomic.take(
            session, Study.gold_item_count, Study.id == study_id, limit=MAX_GOLD_ITEMS
        ):
            raise InputError(f"a study has at most {MAX_GOLD_ITEMS} gold items")
        session.add(item)
    return item


def _check_item(session: Session, study: Study, kind: str, a: int, b: int, answer: int) -> None:
    if kind not in GOLD_KINDS:
        raise InputError(f"kind must be one of {', '.join(GOLD_KINDS)}, got {kind!r}")
    if a == b:
        raise InputError("a gold item needs two different candidates")
    for cid in (a, b):
        if session.get(Candidate, (study.id, cid)) is None:
            raise InputError(f"candidate {cid} is not one of study {study.id}'s candidates")
    if answer not in (a, b):
        raise InputError(f"answer must be {a} or {b}, got {answer}")


def get_item(session: Session, *, study_id: int, item_id: int) -> GoldItem:
    """The study's gold item, or :class:`NotFoundError`."""
    item = session.get(GoldItem, item_id)
    if item is None or item.study_id != study_id:
        raise NotFoundError(f"gold item {item_id} of study {study_id} not found")
    return item


def delete_item(session: Session, *, study_id: int, item_id: int) -> None:
    """Remove a gold item that nobody has answered yet.

    Raises:
        NotFoundError: no such item in this study.
        ConflictError: a participant answered it (their answers are kept).
    """
    item = get_item(session, study_id=study_id, item_id=item_id)
    answered = session.scalar(
        select(func.count())
        .select_from(GoldAnswer)
        .where(GoldAnswer.gold_item_id == item_id, GoldAnswer.winner.is_not(None))
    )
    if answered:
        raise ConflictError(f"gold item {item_id} has {answered} answers; it is kept")
    with writing(session):
        gone = session.execute(delete(GoldItem).where(GoldItem.id == item.id))
        if not cast(CursorResult[Any], gone).rowcount:  # a concurrent call removed it first
            raise NotFoundError(f"gold item {item_id} of study {study_id} not found")
        atomic.give_back(session, Study.gold_item_count, Study.id == study_id)
    session.expunge(item)
