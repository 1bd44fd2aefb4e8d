"""The researcher's live dashboard of a study (issue 29 §1): who joined, is labelling, has
finished or declined; each participant's progress, median time per decision, flags and gold
accuracy; and labels per minute.

The study page polls it every few seconds while hundreds of people label, so a poll is a
fixed number of aggregate statements, whatever the crowd's size:

- :func:`snapshot`: ONE ``SELECT`` of aggregates (label count, newest label id and labels of
  the last 1 and 5 minutes; participants, finished and excluded; gold and consistency
  answers; the open link's counts and options). Its :attr:`Snapshot.etag` changes whenever
  anything the dashboard shows does, so an unchanged dashboard (``If-None-Match``) costs
  this one statement and nothing else.
- :func:`dashboard`: the snapshot plus ONE ``SELECT`` of one row per participant, joining
  grouped subqueries of their labels (count, left choices, response times as one text),
  gold answers and consistency check (:mod:`app.labelling.dashboard_sql`).

Python takes each participant's median of their at most N - 1 times (4,500 in all for 300
people through a 16-candidate bracket: about half a millisecond); a window function ranking
them in SQL cost SQLite more than the whole statement does now. The flags are
:mod:`app.labelling.quality`'s; the two that need a test (the binomial test of position
bias, the Clopper-Pearson bound of the gate) are cached by their integer arguments, of
which a study has few distinct values. ``python benchmarks/dashboard_poll.py`` (300
participants x 15 labels, SQLite, a loaded 2-core machine): a full poll 4 to 6 times a
``GET /api/studies/{id}``, a 304 2 to 3 times.
"""

from __future__ import annotations

import hashlib
import statistics
from dataclasses import astuple, dataclass
from datetime import datetime, timedelta
from typing import Any, Literal

from sqlalchemy import Row
from sqlalchemy.orm import Session

from app.core.errors import NotFoundError
from app.labelling.dashboard_sql import ROWS, SNAPSHOT
from app.labelling.gold_answers import GoldScore
from app.labelling.participant_quality import flags_of, is_fast
from app.labelling.participants import n_matches
from app.models import as_utc, utcnow
from app.studies.crowd import DEFAULT_SPEED_THRESHOLD_MS

Status = Literal["not_started", "labelling", "finished", "withdrawn", "failed_gate", "timed_out"]
#: Bumped when the dashboard's body changes shape, so that no old ETag matches a new body.
FORMAT = 1


@dataclass(frozen=True)
class Snapshot:
    """The study's aggregates, read in one statement: enough to tell whether anything the
    dashboard shows has changed (:attr:`etag`), and its study-wide numbers."""

    study_id: int
    n_candidates: int
    labels: int
    last_label: int
    response_ms_total: int
    last_minute: int
    last_5_minutes: int
    people: int
    last_person: int
    finished: int
    excluded: int
    excluded_ids: int
    withdrawn: int
    timed_out: int
    gold_answers: int
    checks: int
    link_joined: int | None
    declines: int | None
    max_participants: int | None
    speed_threshold_ms: int | None
    gold_gate: float | None

    @property
    def etag(self) -> str:
        """A strong ETag of everything above (and :data:`FORMAT`)."""
        digest = hashlib.sha256(repr((FORMAT, *astuple(self))).encode()).hexdigest()
        return f'"{digest[:24]}"'


def snapshot(session: Session, *, study_id: int, now: datetime | None = None) -> Snapshot:
    """The study's aggregates now (one statement).

    Raises:
        NotFoundError: no such study.
    """
    now = now or utcnow()
    params = {
        "sid": study_id,
        "now": now,
        "minute_ago": now - timedelta(minutes=1),
        "five_ago": now - timedelta(minutes=5),
    }
    row = session.execute(SNAPSHOT, params).one_or_none()
    if row is None:
        raise NotFoundError(f"study {study_id} not found")
    return Snapshot(**{name: _plain(v) for name, v in row._mapping.items()})


def _plain(value: Any) -> Any:
    """A number as Python's own type (PostgreSQL sums are ``Decimal``, SQLite booleans 0/1)."""
    return value if value is None or isinstance(value, float) else int(value)


def etag_matches(if_none_match: str | None, etag: str) -> bool:
    """Whether an ``If-None-Match`` header names ``etag`` (weak or strong, or ``*``)."""
    if not if_none_match:
        return False
    tags = {t.strip().removeprefix("W/") for t in if_none_match.split(",")}
    return "*" in tags or etag in tags


@dataclass(frozen=True)
class LiveParticipant:
    """One participant as the dashboard shows them; ``flags`` as
    :attr:`app.labelling.participant_quality.ParticipantQuality.flags`."""

    id: int
    name: str | None
    external_id: str | None
    status: Status
    done: int
    total: int
    median_response_ms: float | None
    gold_right: int
    gold_asked: int
    excluded: bool
    flags: list[str]


@dataclass(frozen=True)
class Counts:
    """How many participants are where: ``joined`` is all of them (invited or by the open
    link); ``declined`` counts declined consents on the open link, ``withdrawn`` those who
    withdrew after joining, ``timed_out`` those past the link's time limit unfinished."""

    joined: int
    not_started: int
    labelling: int
    finished: int
    declined: int
    excluded: int
    withdrawn: int
    timed_out: int


@dataclass(frozen=True)
class Dashboard:
    """The whole dashboard; ``version`` is :attr:`Snapshot.etag`."""

    study_id: int
    version: str
    as_of: datetime
    counts: Counts
    labels: int
    labels_last_minute: int
    labels_per_minute: float
    max_participants: int | None
    speed_threshold_ms: int
    gold_gate: float | None
    participants: list[LiveParticipant]


def dashboard(
    session: Session, *, study_id: int, known: Snapshot | None = None, now: datetime | None = None
) -> Dashboard:
    """The study's live dashboard (two statements; one when ``known`` is the snapshot the
    caller has just read).

    Raises:
        NotFoundError: no such study.
    """
    now = now or utcnow()
    snap = known or snapshot(session, study_id=study_id, now=now)
    rules = _Rules(snap.speed_threshold_ms or DEFAULT_SPEED_THRESHOLD_MS, snap.gold_gate)
    total = n_matches(snap.n_candidates)
    rows = session.execute(ROWS, {"sid": study_id})
    people = [_live(row, total, rules, now) for row in rows]
    return Dashboard(
        study_id,
        snap.etag,
        now,
        _counts(people, snap.declines or 0),
        snap.labels,
        snap.last_minute,
        snap.last_5_minutes / 5,
        snap.max_participants,
        rules.threshold_ms,
        snap.gold_gate,
        people,
    )


def _counts(people: list[LiveParticipant], declined: int) -> Counts:
    by_status = {s: sum(p.status == s for p in people) for s in ("not_started", "labelling")}
    return Counts(
        len(people),
        by_status["not_started"],
        by_status["labelling"],
        sum(p.status == "finished" for p in people),
        declined,
        sum(p.excluded for p in people),
        sum(p.status == "withdrawn" for p in people),
        sum(p.status == "timed_out" for p in people),
    )


@dataclass(frozen=True)
class _Rules:
    threshold_ms: int
    gate: float | None


def _live(row: Row[Any], total: int, rules: _Rules, now: datetime) -> LiveParticipant:
    """A participant's row of :data:`~app.labelling.dashboard_sql.ROWS`, with their flags."""
    median = _median(row.times)
    done = int(row.done)
    status: Status = "labelling" if done else "not_started"
    if row.withdrawn_at is not None:
        status = "withdrawn"
    elif row.gate_stopped_at is not None:
        status = "failed_gate"
    elif row.finished_at is not None:
        status = "finished"
    elif row.deadline_at is not None and as_utc(row.deadline_at) <= now:
        status = "timed_out"
    return LiveParticipant(
        id=row.id,
        name=row.name,
        external_id=row.external_id,
        status=status,
        done=done,
        total=total,
        median_response_ms=median,
        gold_right=int(row.right),
        gold_asked=int(row.asked),
        excluded=bool(row.excluded),
        flags=_flags(row, median, rules),
    )


def _flags(row: Row[Any], median: float | None, rules: _Rules) -> list[str]:
    """The quality table's flags (:func:`app.labelling.participant_quality.flags_of`) from
    the row."""
    return flags_of(
        left=int(row.left),
        sided=int(row.sided),
        fast=is_fast(median, rules.threshold_ms),
        consistent=None if row.agrees is None else bool(row.agrees),
        gold=GoldScore(int(row.right), int(row.asked)),
        gate=rules.gate,
    )


def _median(times: str | None) -> float | None:
    """The median of a participant's response times, sent as one text (``"1200,950"``)."""
    return None if not times else float(statistics.median(int(t) for t in times.split(",")))
