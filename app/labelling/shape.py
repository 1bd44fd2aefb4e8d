"""A ready study's bracket shape, read once per process: its size, first-round byes and
seed never change once the study is ready (participants exist only in ready studies)."""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass

from sqlalchemy import Connection, Engine, select
from sqlalchemy.orm import Session

from app.db import engine_of
from app.models import BracketSlot, Study


@dataclass(frozen=True)
class BracketShape:
    """A ready study's bracket: ``n`` candidates and the first round's byes; ``seed`` is the
    study's (it seeds which side each match shows on the left, and the coin of a tie);
    ``allow_ties``: whether a participant may answer "can't tell"; ``clips``: whether the
    study opted in to motion clips (each pair shows them once both are rendered)."""

    n: int
    first_round: tuple[tuple[int, int | None], ...]  # (a, b) by slot; b is None for a bye
    byes: dict[int, int]  # first-round slot -> its lone player
    real_before: tuple[int, ...]  # first-round slot -> real matches in earlier slots
    seed: int = 0
    allow_ties: bool = False
    clips: bool = False

    @property
    def n_rounds(self) -> int:
        return (self.n - 1).bit_length()

    def position(self, rnd: int, slot: int) -> tuple[int, int]:
        """``(number, in_round)``: "match ``number`` of ``in_round``" of this round."""
        size = 1 << self.n_rounds  # first-round slots x 2
        if rnd == 1:  # byes are not matches: count the real ones before this slot
            return 1 + self.real_before[slot], self.n - size // 2
        return slot + 1, size >> rnd


#: Bracket shapes by database (engine), then study id.
_shapes: weakref.WeakKeyDictionary[Engine, dict[int, BracketShape]] = weakref.WeakKeyDictionary()
_shapes_lock = threading.Lock()


def shape_of(db: Session | Connection, study_id: int) -> BracketShape:
    """The study's bracket shape, read once per process and database (it is fixed once the
    study is ready, and participants exist only in ready studies)."""
    engine = engine_of(db)
    if (shape := _shapes.get(engine, {}).get(study_id)) is not None:
        return shape
    n, seed, allow_ties, clips = db.execute(
        select(Study.n_candidates, Study.seed, Study.allow_ties, Study.clips).where(
            Study.id == study_id
        )
    ).one()
    slots = tuple(
        (a, b)
        for a, b in db.execute(
            select(BracketSlot.a, BracketSlot.b)
            .where(BracketSlot.study_id == study_id)
            .order_by(BracketSlot.slot)
        )
    )
    real_before, count = [], 0
    for _, b in slots:
        real_before.append(count)
        count += b is not None
    shape = BracketShape(
        n,
        slots,
        {s: a for s, (a, b) in enumerate(slots) if b is None},
        tuple(real_before),
        seed,
        allow_ties,
        clips,
    )
    with _shapes_lock:
        return _shapes.setdefault(engine, {}).setdefault(study_id, shape)
