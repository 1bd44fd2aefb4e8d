"""Tree-reading surveys, the paper's user study (app/surveys)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    ColumnElement,
    DateTime,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
    func,
)
from sqlalchemy.ext.hybrid import hybrid_property
from sqlalchemy.orm import Mapped, mapped_column, synonym

from app.models.base import (
    Base,
    utcnow,
)
from app.models.people import Member, OpenLink

SURVEY_ASSIGNMENTS = ("all", "round_robin")
SURVEY_EXCLUSIONS = ("none", "attention_check")


class Survey(Base):
    """A tree-reading survey: intro, questions (JSON, the same on every stimulus), options.

    ``assignment`` is ``all`` (every respondent sees every stimulus) or ``round_robin`` (one
    stimulus each, from ``rr_counter``, a counter the database increments atomically).
    ``exclusion_rule`` is fixed when the survey is created (it opens at once) and never
    changes; ``seed`` seeds every respondent's order and left/right placement.
    """

    __tablename__ = "surveys"
    __table_args__ = (
        CheckConstraint("assignment IN ('all', 'round_robin')", name="assignment"),
        CheckConstraint("exclusion_rule IN ('none', 'attention_check')", name="exclusion_rule"),
        CheckConstraint("rr_counter >= 0", name="rr_counter"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    intro: Mapped[str] = mapped_column(Text)
    template: Mapped[str] = mapped_column(String(16))
    questions: Mapped[list] = mapped_column(JSON)
    highlights: Mapped[bool] = mapped_column(Boolean, default=False)
    assignment: Mapped[str] = mapped_column(String(16))
    exclusion_rule: Mapped[str] = mapped_column(String(32))
    seed: Mapped[int] = mapped_column(BigInteger)
    rr_counter: Mapped[int] = mapped_column(Integer, default=0)
    #: Its webhooks, counted as a study's are (:attr:`Study.webhook_count`).
    webhook_count: Mapped[int] = mapped_column(Integer, default=0)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class SurveyStimulus(Base):
    """Two frozen ``acv.tree/1`` trees ("Tree 1", "Tree 2") shown on one screen.

    ``trees`` is ``[{"name", "source", "study_id", "doc", "highlight"}, ...]`` (two items):
    the document is copied in when the survey is created, so later changes to a participant or
    a run never change what respondents saw. ``expected`` overrides the questions' expected
    answers on this stimulus; an attention check asks only its ``check_question``.
    """

    __tablename__ = "survey_stimuli"
    __table_args__ = (UniqueConstraint("survey_id", "position"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    survey_id: Mapped[int] = mapped_column(ForeignKey("surveys.id", ondelete="CASCADE"))
    position: Mapped[int] = mapped_column(Integer)
    label: Mapped[str] = mapped_column(String(200))
    attention_check: Mapped[bool] = mapped_column(Boolean, default=False)
    check_question: Mapped[str | None] = mapped_column(String(32), default=None)
    trees: Mapped[list] = mapped_column(JSON)
    expected: Mapped[dict] = mapped_column(JSON)


class SurveyRespondent(Member):
    """Someone answering a survey, known only by their invite token (a member of kind
    ``survey``, as a participant is of a study).

    ``started_at`` is set once, by whichever request first plans their screens (an atomic
    ``UPDATE ... WHERE started_at IS NULL``); ``stimulus_id`` is their round-robin stimulus.
    ``former_id`` is the id a respondent had before members were one table (revision 0017
    gave them new ids above every participant's): exports, payloads and their screen plan
    keep showing and using it (:attr:`shown_id`).
    """

    __tablename__ = "survey_respondents"
    __mapper_args__ = {"polymorphic_identity": "survey"}

    id: Mapped[int] = mapped_column(ForeignKey("members.id", ondelete="CASCADE"), primary_key=True)
    stimulus_id: Mapped[int | None] = mapped_column(
        ForeignKey("survey_stimuli.id", ondelete="CASCADE"), default=None
    )
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    former_id: Mapped[int | None] = mapped_column(Integer, unique=True, default=None)
    #: Their survey (the member's collection).
    survey_id = synonym("collection_id")

    @hybrid_property
    def shown_id(self) -> int:
        """The id exports, webhook payloads and the screen plan's seed use."""
        return self.id if self.former_id is None else self.former_id

    @shown_id.inplace.expression
    @classmethod
    def _shown_id(cls) -> ColumnElement[int]:
        return func.coalesce(cls.former_id, cls.id)


class SurveyCrowdSettings(OpenLink):
    """A survey's open link ``/q/<slug>`` (app.surveys.crowd); it has no options of its own."""

    __mapper_args__ = {"polymorphic_identity": "survey"}

    #: The survey whose link this is.
    survey_id = synonym("collection_id")


class SurveyScreen(Base):
    """One screen of a respondent's plan: which stimulus, and whether Tree 1 is on the left.

    ``shown_at`` is when the server first sent it, ``screen_ms`` the time on the screen that
    the page measured in the visit that answered it, ``answered_at`` when the answers came.
    """

    __tablename__ = "survey_screens"
    __table_args__ = (
        UniqueConstraint("respondent_id", "stimulus_id"),
        CheckConstraint("screen_ms >= 0", name="screen_ms"),
    )

    respondent_id: Mapped[int] = mapped_column(
        ForeignKey("survey_respondents.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    stimulus_id: Mapped[int] = mapped_column(ForeignKey("survey_stimuli.id", ondelete="CASCADE"))
    tree1_left: Mapped[bool] = mapped_column(Boolean)
    shown_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    answered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    screen_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)


class SurveyAnswer(Base):
    """A respondent's answer to one question on one stimulus; final (UNIQUE per question)."""

    __tablename__ = "survey_answers"
    __table_args__ = (
        UniqueConstraint("respondent_id", "stimulus_id", "question"),
        CheckConstraint(
            "confidence IS NULL OR (confidence >= 1 AND confidence <= 5)", name="confidence"
        ),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    respondent_id: Mapped[int] = mapped_column(
        ForeignKey("survey_respondents.id", ondelete="CASCADE"), index=True
    )
    stimulus_id: Mapped[int] = mapped_column(ForeignKey("survey_stimuli.id", ondelete="CASCADE"))
    question: Mapped[str] = mapped_column(String(32))
    value: Mapped[str] = mapped_column(Text)
    confidence: Mapped[int | None] = mapped_column(Integer, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
