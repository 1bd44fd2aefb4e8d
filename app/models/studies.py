"""A study's tables (app/studies, app/labelling).

A study owns its candidates (ids ``0 .. N-1``, as in ``acv.tree/1``) and its first-round
bracket; each participant plays the whole bracket on their own. A match row exists once both
of its players are known, and holds at most one label: ``labels.match_id`` is UNIQUE, so the
database itself refuses a second decision of a match.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    ForeignKeyConstraint,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column, synonym

from app.models.base import (
    Base,
    StudyStatus,
    enum_type,
    status_check,
    utcnow,
)
from app.models.people import Member, OpenLink


class Study(Base):
    """A labelling study: env, candidate count, seeding parameters and instructions."""

    __tablename__ = "studies"
    __table_args__ = (
        CheckConstraint("n_candidates >= 2 AND n_candidates <= 128", name="n_candidates"),
        CheckConstraint("p >= 0 AND p <= 1", name="p"),
        status_check(StudyStatus),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    env_id: Mapped[str] = mapped_column(String(100))
    n_candidates: Mapped[int] = mapped_column(Integer)
    p: Mapped[float] = mapped_column(Float)
    seed: Mapped[int] = mapped_column(BigInteger)
    sampling: Mapped[str] = mapped_column(String(16))
    instructions: Mapped[str] = mapped_column(Text)
    #: Extra pairs each participant is asked after the bracket (:class:`DisagreementPair`).
    disagreement_pairs: Mapped[int] = mapped_column(Integer, default=0)
    #: A participant may answer "can't tell"; the bracket then advances by a seeded coin.
    allow_ties: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Practice pairs shown before the bracket (0, or 2 to 5); never stored as labels.
    practice_pairs: Mapped[int] = mapped_column(Integer, default=0)
    #: Motion clips of the candidates, opted in by the researcher (issue 41 §3); they render
    #: after the study is ready, and ``clips_ready`` says when every one has.
    clips: Mapped[bool] = mapped_column(Boolean, default=False)
    clips_ready: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Its webhooks and gold items, counted in the transactions that add and remove them: the
    #: database caps them (:func:`app.core.atomic.take`), never a count read beforehand.
    webhook_count: Mapped[int] = mapped_column(Integer, default=0)
    gold_item_count: Mapped[int] = mapped_column(Integer, default=0)
    status: Mapped[StudyStatus] = mapped_column(
        enum_type(StudyStatus), default=StudyStatus.PREPARING
    )
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class Candidate(Base):
    """A candidate state of a study: enough to restore it, its reward and its images.

    ``qpos`` and ``qvel`` are JSON lists of floats (exact: JSON keeps ``repr`` digits); the
    image paths are relative to the data dir.
    """

    __tablename__ = "candidates"

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True
    )
    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    qpos: Mapped[list[float]] = mapped_column(JSON)
    qvel: Mapped[list[float]] = mapped_column(JSON)
    env_reward: Mapped[float] = mapped_column(Float)
    image_path: Mapped[str] = mapped_column(String(255))
    thumb_path: Mapped[str] = mapped_column(String(255))
    #: The study's no-advice baseline's return from this state (studies that ask
    #: disagreement pairs; NULL otherwise).
    baseline_return: Mapped[float | None] = mapped_column(Float, default=None)
    #: The candidate's clip (studies with clips; NULL until rendered), and the policy and reset
    #: seed that rolled it forward from this state.
    clip_path: Mapped[str | None] = mapped_column(String(255), default=None)
    clip_policy: Mapped[str | None] = mapped_column(String(100), default=None)
    clip_seed: Mapped[int | None] = mapped_column(BigInteger, default=None)


class BracketSlot(Base):
    """One slot of a study's first round, in bracket order: ``b`` is NULL for a bye."""

    __tablename__ = "bracket_slots"
    __table_args__ = (
        ForeignKeyConstraint(
            ["study_id", "a"], ["candidates.study_id", "candidates.id"], ondelete="CASCADE"
        ),
        ForeignKeyConstraint(
            ["study_id", "b"], ["candidates.study_id", "candidates.id"], ondelete="CASCADE"
        ),
    )

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True
    )
    slot: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int | None] = mapped_column(Integer, default=None)


class Participant(Member):
    """Someone labelling a study's bracket, known only by their invite token (a member of
    kind ``study``; their activity and exclusion are this table's own)."""

    __tablename__ = "participants"
    __mapper_args__ = {"polymorphic_identity": "study"}

    id: Mapped[int] = mapped_column(ForeignKey("members.id", ondelete="CASCADE"), primary_key=True)
    last_active_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: Left out of pooling and exports (by the researcher, or by the gold gate when it
    #: excludes); their labels are kept.
    excluded: Mapped[bool] = mapped_column(Boolean, default=False)
    exclusion_reason: Mapped[str | None] = mapped_column(String(200), default=None)
    #: When the gold gate stopped them mid-study (after 2 or more failed gold items).
    gate_stopped_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: Their study (the member's collection).
    study_id = synonym("collection_id")


class Match(Base):
    """A match of one participant's bracket whose two players are known."""

    __tablename__ = "matches"
    __table_args__ = (
        UniqueConstraint("participant_id", "round", "slot"),
        CheckConstraint("a <> b", name="distinct_players"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participants.id", ondelete="CASCADE"))
    round: Mapped[int] = mapped_column(Integer)
    slot: Mapped[int] = mapped_column(Integer)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: Whether ``a`` is shown on the left (seeded per study, participant and match).
    a_left: Mapped[bool] = mapped_column(Boolean, default=True)


class Label(Base):
    """A participant's decision of a match; at most one per match (UNIQUE ``match_id``)."""

    __tablename__ = "labels"
    __table_args__ = (CheckConstraint("response_ms >= 0", name="response_ms"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    match_id: Mapped[int] = mapped_column(ForeignKey("matches.id", ondelete="CASCADE"), unique=True)
    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), index=True
    )
    winner: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)
    #: Whether the picture on the left won (NULL for labels stored before sides were kept).
    chose_left: Mapped[bool | None] = mapped_column(Boolean, default=None)
    #: The participant could not tell; ``winner`` is the seeded coin's (docs/method.md §2.14).
    tie: Mapped[bool] = mapped_column(Boolean, default=False)
    #: What the pair showed: ``still`` or ``clip`` (issue 41 §3).
    stimulus: Mapped[str] = mapped_column(String(8), default="still")


class CrowdSettings(OpenLink):
    """A study's open link ``/s/<slug>`` and its quality options (app.studies.crowd), the
    options in this table."""

    __tablename__ = "study_link_options"
    __table_args__ = (CheckConstraint("speed_threshold_ms >= 0", name="speed"),)
    __mapper_args__ = {"polymorphic_identity": "study"}

    id: Mapped[int] = mapped_column(
        ForeignKey("open_links.id", ondelete="CASCADE"), primary_key=True
    )
    consistency_check: Mapped[bool] = mapped_column(Boolean, default=False)
    speed_threshold_ms: Mapped[int] = mapped_column(Integer, default=800)
    #: The qualification gate: a participant whose gold accuracy's upper confidence bound is
    #: below it is flagged (``None``: no gate).
    gold_gate: Mapped[float | None] = mapped_column(Float, default=None)
    #: Whether the gate also excludes the participants it flags.
    gate_excludes: Mapped[bool] = mapped_column(Boolean, default=False)
    #: The code of a participant the gate stops (it excludes them after 2 or more failed gold
    #: items).
    gate_code: Mapped[str | None] = mapped_column(String(100), default=None)
    #: The study whose link this is.
    study_id = synonym("collection_id")


class ConsistencyCheck(Base):
    """After the bracket, one first-round match shown again with its sides swapped (not
    part of the bracket); ``winner`` is the answer, compared with the match's label."""

    __tablename__ = "consistency_checks"

    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), primary_key=True
    )
    match_id: Mapped[int] = mapped_column(ForeignKey("matches.id", ondelete="CASCADE"))
    a_left: Mapped[bool] = mapped_column(Boolean)
    winner: Mapped[int | None] = mapped_column(Integer, default=None)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)
    shown_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    answered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: What the pair showed when answered: ``still`` or ``clip`` (issue 41 §3).
    stimulus: Mapped[str] = mapped_column(String(8), default="still")


class DisagreementPair(Base):
    """After the bracket, a pair where the participant's advice and a no-advice baseline
    disagree (:mod:`engine.disagreement`): labelled and exported like a match, never part of
    the tree. ``a`` is the advice's pick, ``b`` the baseline's; ``winner`` is the answer."""

    __tablename__ = "disagreement_pairs"

    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int] = mapped_column(Integer)
    a_left: Mapped[bool] = mapped_column(Boolean)
    winner: Mapped[int | None] = mapped_column(Integer, default=None)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)
    shown_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    answered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: What the pair showed when answered: ``still`` or ``clip`` (issue 41 §3).
    stimulus: Mapped[str] = mapped_column(String(8), default="still")


class GoldItem(Base):
    """A pair with an objective answer, shown among the bracket's matches (never part of
    it). ``kind`` is ``pair`` (written and answered by the researcher) or ``instructed``
    (``answer`` is shown with a marker: "choose the picture with the marker")."""

    __tablename__ = "gold_items"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(16))
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int] = mapped_column(Integer)
    answer: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class GoldAnswer(Base):
    """A participant's copy of a gold item: shown once ``position`` bracket matches are
    decided, with ``a`` on the left when ``a_left``; ``winner`` is their answer."""

    __tablename__ = "gold_answers"

    participant_id: Mapped[int] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), primary_key=True
    )
    gold_item_id: Mapped[int] = mapped_column(
        ForeignKey("gold_items.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(Integer)
    a_left: Mapped[bool] = mapped_column(Boolean)
    winner: Mapped[int | None] = mapped_column(Integer, default=None)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)
    answered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
