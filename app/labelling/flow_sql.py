"""The hot path's statements (:mod:`app.labelling.flow`), built once with bound parameters
(``pid``: the participant; ``mid``: the match; ``now``: the time of the request), so that a
request constructs no statement and walks no cache key."""

from __future__ import annotations

from sqlalchemy import BindParameter, bindparam, func, insert, select, update
from sqlalchemy.orm import aliased

from app.models import Candidate, Label, Match, Member, Participant
from app.recruiting.seats import within_time

PID: BindParameter[int] = bindparam("pid")
MID: BindParameter[int] = bindparam("mid")
DONE = select(func.count(Label.id)).where(Label.participant_id == PID).scalar_subquery()
OPEN = (
    select(Match.id, Match.round, Match.slot, Match.a, Match.b, Match.a_left)
    .outerjoin(Label, Label.match_id == Match.id)
    .where(Match.participant_id == PID, Label.id.is_(None))
    .order_by(Match.round, Match.slot)
    .limit(1)
)
OPEN_AND_DONE = OPEN.add_columns(DONE)
#: The first statement of a label's transaction: takes the participant's lock.
#: Matches only a participant who may still label: not withdrawn, not past their time.
LOCK = (
    update(Member)
    .where(Member.id == PID, Member.collection_kind == "study", within_time(bindparam("now")))
    .values(finished_at=Member.finished_at)
)
#: Why :data:`LOCK` matched nobody.
LOCKED_OUT = select(Participant.withdrawn_at, Participant.gate_stopped_at).where(
    Participant.id == PID
)
_sibling, _sibling_label = aliased(Match), aliased(Label)
#: The winner of the slot whose winner meets this match's (slots 2k and 2k + 1 pair up).
SIBLING_WINNER = (
    select(_sibling_label.winner)
    .join(_sibling, _sibling.id == _sibling_label.match_id)
    .where(
        _sibling.participant_id == PID,
        _sibling.round == Match.round,
        _sibling.slot == Match.slot + 1 - 2 * (Match.slot % 2),
    )
    .scalar_subquery()
)
MATCH_ROW = (
    select(
        Match.round,
        Match.slot,
        Match.a,
        Match.b,
        Match.a_left,
        Match.created_at,
        Label.winner,
        Label.tie,
        Participant.last_active_at,
        DONE,
        SIBLING_WINNER,
    )
    .join(Participant, Participant.id == Match.participant_id)
    .outerjoin(Label, Label.match_id == Match.id)
    .where(Match.id == MID, Match.participant_id == PID)
)
INSERT_LABEL, INSERT_MATCH = insert(Label), insert(Match)
TOUCH = update(Participant).where(Participant.id == PID).values(last_active_at=bindparam("now"))
FINISH = update(Member).where(Member.id == PID).values(finished_at=bindparam("now"))
#: How many of a pair's two candidates (``sid``, ``a``, ``b``) have their clip rendered.
PAIR_CLIPS = select(func.count()).where(
    Candidate.study_id == bindparam("sid"),
    Candidate.id.in_((bindparam("a"), bindparam("b"))),
    Candidate.clip_path.is_not(None),
)
LABEL_WINNER = select(Label.winner, Label.tie).where(Label.match_id == MID)
DONE_ONLY = select(DONE)
