"""Seats on an open link and what became of each member (issue 45 §1-2), for studies and
surveys alike.

A member who joins through an open link takes a seat (:func:`app.recruiting.links.take_seat`).
The seat is given back once, by whichever comes first: they withdraw (:func:`withdraw`), or
they pass the link's time limit without finishing (:func:`free_expired_seats`, run by the
next join, in its transaction). Each is one ``UPDATE ... WHERE seat_freed_at IS NULL`` on the
members and one on the link's ``joined``, so two joins at once free a seat once, and the
link's CHECK still holds ``joined <= max_participants``. A member past their time can do
nothing more (the label path refuses them in the statement that takes their lock), so seats
in use never outnumber seats.

Every member ends with an :class:`Outcome`, and the link maps each to a code the platform
knows: finished (``completion_code``), withdrawn or declined (``decline_code``), stopped by
the gold gate (``gate_code``, studies only); timed out gets none (the platform times them
out itself).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, Literal, cast
from urllib.parse import quote

from sqlalchemy import ColumnElement, Connection, CursorResult, and_, or_, update
from sqlalchemy.orm import Session
from sqlalchemy.orm.attributes import set_committed_value

from app.core.errors import ServiceError
from app.models import Member, OpenLink, Participant, as_utc
from app.recruiting.members import of_collection

OutcomeName = Literal["in_progress", "finished", "withdrawn", "failed_gate", "timed_out"]
OUTCOMES: tuple[OutcomeName, ...] = (
    "in_progress",
    "finished",
    "withdrawn",
    "failed_gate",
    "timed_out",
)


class MemberEndedError(ServiceError):
    """The member withdrew, or their time is over: they can do nothing more here (410).
    ``noun``: what has ended for them (a member's ``collection_kind``), in the page's title."""

    status_code = 410

    def __init__(self, detail: str, *, noun: str = "study") -> None:
        super().__init__(detail)
        self.title = f"This {noun} has ended for you"


@dataclass(frozen=True)
class Outcome:
    """What became of a member, and the code they are given for it (``None``: no code)."""

    name: OutcomeName
    code: str | None

    @property
    def ended(self) -> bool:
        """Whether they can do nothing more but read their outcome."""
        return self.name in ("withdrawn", "failed_gate", "timed_out")


@dataclass(frozen=True)
class Ending:
    """What a member who came through an open link is shown as they end: their outcome's
    code, and where to go back to the platform (``None``: nowhere)."""

    code: str | None
    redirect_url: str | None


def ending(link: OpenLink | None, result: Outcome) -> Ending | None:
    """The code and redirect of ``result`` on ``link``. The redirect URL takes the code in
    place of ``{code}`` (Prolific's ``...?cc={code}``); one without it is the finishers' own
    (their return to the platform), as before codes per outcome."""
    if link is None or result.name == "in_progress":
        return None
    url, code = link.redirect_url, result.code
    if url is not None and "{code}" in url:
        url = url.replace("{code}", quote(code, safe="")) if code is not None else None
    elif result.name != "finished":
        url = None
    return Ending(code, url)


def deadline(link: OpenLink, now: datetime) -> datetime | None:
    """When a member joining ``link`` at ``now`` runs out of time (``None``: no limit)."""
    return None if link.time_limit_min is None else now + timedelta(minutes=link.time_limit_min)


def timed_out(member: Member, now: datetime) -> bool:
    """Whether ``member`` passed their deadline without finishing or withdrawing."""
    return (
        member.deadline_at is not None
        and member.finished_at is None
        and member.withdrawn_at is None
        and as_utc(member.deadline_at) <= now
    )


def minutes_left(member: Member, now: datetime) -> int | None:
    """Whole minutes (rounded up) before ``member``'s time limit ends; None without one, or
    once they finished."""
    if member.deadline_at is None or member.finished_at is not None:
        return None
    return max(0, math.ceil((as_utc(member.deadline_at) - now).total_seconds() / 60))


def check_can_act(member: Member, now: datetime) -> None:
    """Refuse a member who withdrew or ran out of time (the page's or API's early answer;
    the write itself is guarded by :func:`within_time`).

    Raises:
        MemberEndedError: they withdrew, or their time is over.
    """
    noun = member.collection_kind
    if member.withdrawn_at is not None:
        raise MemberEndedError(
            f"you withdrew from this {noun}: it takes no more answers from you", noun=noun
        )
    if timed_out(member, now):
        raise MemberEndedError(
            f"your time for this {noun} is over: it takes no more answers", noun=noun
        )


def set_share_consent(session: Session, member: Member, *, share: bool) -> None:
    """Record ``member``'s choice to share their answers in a public dataset, inside the
    caller's write transaction; refused once they withdrew (their answers are left out of
    everything, so the choice would mean nothing). One conditional ``UPDATE``, so a
    withdrawal at the same moment wins or loses whole.

    Raises:
        MemberEndedError: they withdrew.
    """
    still_in = and_(Member.id == member.id, Member.withdrawn_at.is_(None))
    if _rowcount(session.execute(_update(Member).where(still_in).values(share_consent=share))):
        set_committed_value(member, "share_consent", share)
        return
    noun = member.collection_kind
    raise MemberEndedError(
        f"you withdrew from this {noun}: your answers are not used, so none can be shared",
        noun=noun,
    )


def lock_in_time(
    db: Session | Connection,
    member_id: int,
    now: datetime,
    *,
    noun: str = "study",
    after_finishing: bool = False,
) -> None:
    """Take ``member_id``'s row lock inside the caller's write transaction, if they may still
    act (:func:`within_time`): the first statement of an answer that is not a label (a gold
    item, a disagreement pair), as the label's own lock is. ``noun``: their kind of
    collection, for the refusal's title; ``after_finishing``: an answer that comes after
    ``finished_at`` (the bracket's consistency check and disagreement pairs), which one who
    finished in time may give after their deadline: the completion code waits on it.

    Raises:
        MemberEndedError: they withdrew, or their time is over (a time limit, or the gate).
    """
    lock = (
        update(Member)
        .where(Member.id == member_id, within_time(now, or_finished=after_finishing))
        .values(finished_at=Member.finished_at)
        .execution_options(synchronize_session=False)
    )
    if _rowcount(db.execute(lock)) == 0:
        raise MemberEndedError(
            "this takes no more answers from you: you withdrew, or your time here is over",
            noun=noun,
        )


def within_time(now: Any, *, or_finished: bool = False) -> ColumnElement[bool]:
    """The condition a member who may still act meets: not withdrawn, not past their time
    (``now``: a datetime or a bound parameter); with ``or_finished``, one who finished counts
    as in time."""
    return and_(Member.withdrawn_at.is_(None), _in_time(now, or_finished=or_finished))


def _in_time(now: Any, *, or_finished: bool) -> ColumnElement[bool]:
    in_time = or_(Member.deadline_at.is_(None), Member.deadline_at > now)
    return or_(Member.finished_at.is_not(None), in_time) if or_finished else in_time


def kept_in_data(
    *, include_excluded: bool, now: datetime, excluded: Any = Participant.excluded
) -> list[ColumnElement[bool]]:
    """The conditions on a member whose answers go into trees, pooling, exports and the
    dataset: never one who withdrew; one excluded (by the researcher or the gate) or timed
    out only with ``include_excluded``. ``excluded`` is the kind's exclusion column
    (participants', or evaluators')."""
    always: list[ColumnElement[bool]] = [Member.withdrawn_at.is_(None)]
    if include_excluded:
        return always
    return [*always, _in_time(now, or_finished=True), excluded.is_(False)]


def outcome(
    member: Member, link: OpenLink | None, now: datetime, *, failed_gate: bool = False
) -> Outcome:
    """``member``'s outcome, and its code on ``link`` (only members who came through the link
    get codes: the codes are what a platform pays or returns against)."""
    name: OutcomeName
    if member.withdrawn_at is not None:
        name = "withdrawn"
    elif failed_gate:
        name = "failed_gate"
    elif member.finished_at is not None:
        name = "finished"
    else:
        name = "timed_out" if timed_out(member, now) else "in_progress"
    return Outcome(name, _code(link, name) if member.via_link else None)


def _code(link: OpenLink | None, name: OutcomeName) -> str | None:
    if link is None:
        return None
    codes: dict[OutcomeName, str | None] = {
        "finished": link.completion_code,
        "withdrawn": link.decline_code,
        "failed_gate": getattr(link, "gate_code", None),  # a study link's own option
    }
    return codes.get(name)


def free_expired_seats(session: Session, link: OpenLink, now: datetime) -> int:
    """Give back the seats of the link's members past their time, inside the caller's write
    transaction; how many."""
    if link.time_limit_min is None:
        return 0
    expired = and_(
        _members_of(link),
        Member.finished_at.is_(None),
        Member.withdrawn_at.is_(None),
        Member.deadline_at <= now,
    )
    return _free(session, link, expired, now)


def withdraw(session: Session, member: Member, link: OpenLink | None, now: datetime) -> bool:
    """Mark ``member`` withdrawn and give back their seat, inside the caller's write
    transaction; whether they were still in (a finished member cannot withdraw here).
    Their answers are kept, and left out of everything."""
    still_in = and_(Member.id == member.id, Member.finished_at.is_(None), within_time(now))
    if _rowcount(session.execute(_update(Member).where(still_in).values(withdrawn_at=now))) == 0:
        return False
    free_seat(session, member, link, now)
    return True


def free_seat(session: Session, member: Member, link: OpenLink | None, now: datetime) -> bool:
    """Give back ``member``'s seat on ``link`` (once; nothing for an invited member), inside
    the caller's write transaction; whether it was given back."""
    if link is None:
        return False
    return _free(session, link, and_(_members_of(link), Member.id == member.id), now) > 0


def _members_of(link: OpenLink) -> ColumnElement[bool]:
    """The members who hold a seat of ``link``."""
    return and_(
        of_collection(link.collection_kind, link.collection_id),
        Member.via_link.is_(True),
        Member.seat_freed_at.is_(None),
    )


def _free(session: Session, link: OpenLink, members: ColumnElement[bool], now: datetime) -> int:
    freed = _rowcount(session.execute(_update(Member).where(members).values(seat_freed_at=now)))
    if freed:
        session.execute(
            _update(OpenLink).where(OpenLink.id == link.id).values(joined=OpenLink.joined - freed)
        )
    return freed


def _update(model: type[Member] | type[OpenLink]) -> Any:
    """An UPDATE that leaves the session's objects alone (SQLite's naive datetimes cannot be
    compared in Python with an aware ``now``; callers refresh what they show)."""
    return update(model).execution_options(synchronize_session=False)


def _rowcount(result: Any) -> int:
    return cast(CursorResult[Any], result).rowcount
