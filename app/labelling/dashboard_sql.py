"""The dashboard's two statements (:mod:`app.labelling.dashboard`), built once with bound
parameters (``sid``: the study; ``minute_ago``, ``five_ago``: the rate's windows).

:data:`SNAPSHOT` is one row of aggregates: crossed one-row subqueries over the study's
labels, participants, and gold and consistency answers, with the study and its open link.
:data:`ROWS` is one row per participant, outer-joining grouped subqueries: their labels
(count, left choices, and their response times as one text), gold answers and consistency
check. Each table is read once, through its index on the participant; Python reads one
row per participant.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import (
    BindParameter,
    ColumnElement,
    String,
    Subquery,
    and_,
    bindparam,
    case,
    cast,
    func,
    select,
    true,
)

from app.models import (
    ConsistencyCheck,
    CrowdSettings,
    GoldAnswer,
    GoldItem,
    Label,
    Participant,
    Study,
)

_SID: BindParameter[int] = bindparam("sid")
_PEOPLE = select(Participant.id).where(Participant.study_id == _SID)
_IN_STUDY = Label.participant_id.in_(_PEOPLE)


def _count_if(condition: ColumnElement[bool], value: Any = 1) -> ColumnElement[int]:
    return func.coalesce(func.sum(case((condition, value), else_=0)), 0)


def _labels_now() -> Subquery:
    return (
        select(
            func.count(Label.id).label("labels"),
            func.coalesce(func.max(Label.id), 0).label("last_label"),
            # SQLite may reuse an undone label's id: the times tell a new label apart
            func.coalesce(func.sum(Label.response_ms), 0).label("response_ms_total"),
            _count_if(Label.created_at >= bindparam("minute_ago")).label("last_minute"),
            _count_if(Label.created_at >= bindparam("five_ago")).label("last_5_minutes"),
        )
        .where(_IN_STUDY)
        .subquery()
    )


#: A participant past their time limit, unfinished and not withdrawn, at ``now``.
_TIMED_OUT = and_(
    Participant.deadline_at <= bindparam("now"),
    Participant.finished_at.is_(None),
    Participant.withdrawn_at.is_(None),
    Participant.gate_stopped_at.is_(None),
)


def _people_now() -> Subquery:
    return (
        select(
            func.count(Participant.id).label("people"),
            func.coalesce(func.max(Participant.id), 0).label("last_person"),
            func.count(Participant.finished_at).label("finished"),
            _count_if(Participant.excluded.is_(True)).label("excluded"),
            # with the count, which participants are excluded (one excluded, another
            # included again between two polls changes the sum)
            _count_if(Participant.excluded.is_(True), Participant.id).label("excluded_ids"),
            _count_if(Participant.withdrawn_at.is_not(None)).label("withdrawn"),
            # time passing changes who is timed out, with no row changed: counted at `now`
            _count_if(_TIMED_OUT).label("timed_out"),
        )
        .where(Participant.study_id == _SID)
        .subquery()
    )


def _answers_now() -> Subquery:
    gold = select(func.count()).where(
        GoldAnswer.winner.is_not(None), GoldAnswer.participant_id.in_(_PEOPLE)
    )
    checks = select(func.count()).where(
        ConsistencyCheck.winner.is_not(None), ConsistencyCheck.participant_id.in_(_PEOPLE)
    )
    return select(
        gold.scalar_subquery().label("gold_answers"), checks.scalar_subquery().label("checks")
    ).subquery()


def _snapshot_statement() -> Any:
    labels, people, answers = _labels_now(), _people_now(), _answers_now()
    return (
        select(
            Study.id.label("study_id"),
            Study.n_candidates,
            *labels.c,
            *people.c,
            *answers.c,
            CrowdSettings.joined.label("link_joined"),
            CrowdSettings.declines,
            CrowdSettings.max_participants,
            CrowdSettings.speed_threshold_ms,
            CrowdSettings.gold_gate,
        )
        .select_from(Study)
        .outerjoin(CrowdSettings, CrowdSettings.study_id == Study.id)
        .join(labels, true())
        .join(people, true())
        .join(answers, true())
        .where(Study.id == _SID)
    )


#: The study's aggregates (:class:`app.labelling.dashboard.Snapshot`, in its field order).
SNAPSHOT = _snapshot_statement()


def _label_stats() -> Subquery:
    """Each participant's labels, in one grouped pass: how many, their left choices, and
    their response times as one text (``"1200,950,..."``, in no order; ``group_concat`` on
    SQLite, ``string_agg`` on PostgreSQL), whose median Python takes. A window function
    ranking the times costs SQLite three times as much as this whole pass."""
    return (
        select(
            Label.participant_id.label("pid"),
            func.count(Label.id).label("done"),
            _count_if(Label.chose_left.is_(True)).label("left"),
            func.count(Label.chose_left).label("sided"),
            func.aggregate_strings(cast(Label.response_ms, String), ",").label("times"),
        )
        .where(_IN_STUDY)
        .group_by(Label.participant_id)
        .subquery()
    )


def _gold_stats() -> Subquery:
    return (
        select(
            GoldAnswer.participant_id.label("pid"),
            func.count().label("asked"),
            _count_if(GoldAnswer.winner == GoldItem.answer).label("right"),
        )
        .join(GoldItem, GoldItem.id == GoldAnswer.gold_item_id)
        .where(GoldItem.study_id == _SID, GoldAnswer.winner.is_not(None))
        .group_by(GoldAnswer.participant_id)
        .subquery()
    )


def _check_stats() -> Subquery:
    """Whether each participant's answered consistency checks all agree with their label."""
    return (
        select(
            ConsistencyCheck.participant_id.label("pid"),
            func.min(case((ConsistencyCheck.winner == Label.winner, 1), else_=0)).label("agrees"),
        )
        .join(Label, Label.match_id == ConsistencyCheck.match_id)
        .where(_IN_STUDY, ConsistencyCheck.winner.is_not(None))
        .group_by(ConsistencyCheck.participant_id)
        .subquery()
    )


def _rows_statement() -> Any:
    labels, gold, checks = _label_stats(), _gold_stats(), _check_stats()
    return (
        select(
            Participant.id,
            Participant.name,
            Participant.external_id,
            Participant.excluded,
            Participant.finished_at,
            Participant.withdrawn_at,
            Participant.deadline_at,
            Participant.gate_stopped_at,
            func.coalesce(labels.c.done, 0).label("done"),
            func.coalesce(labels.c.left, 0).label("left"),
            func.coalesce(labels.c.sided, 0).label("sided"),
            labels.c.times,
            func.coalesce(gold.c.asked, 0).label("asked"),
            func.coalesce(gold.c.right, 0).label("right"),
            checks.c.agrees,
        )
        .outerjoin(labels, labels.c.pid == Participant.id)
        .outerjoin(gold, gold.c.pid == Participant.id)
        .outerjoin(checks, checks.c.pid == Participant.id)
        .where(Participant.study_id == _SID)
        .order_by(Participant.id)
    )


#: One row per participant, in id order.
ROWS = _rows_statement()
