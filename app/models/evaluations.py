"""Agent evaluations (app/evaluations, issue 41): a person shown what two trained agents do,
asked which one does what was asked.

An evaluation is a third kind of collection: its members are *evaluators* (``members`` rows
of kind ``evaluation``, invited by ``/v/<token>``). Its runs sit in slots ``0 .. 2k-1``
(``evaluation_runs``); what a slot's agent does is rendered once into stimuli
(``evaluation_stimuli``: a still per window, and a clip once clips are rendered). Each
evaluator answers their own pairs (``evaluation_pairs``), whose stimuli are served under the
pair's opaque ``key`` only: no run id, slot, arm, seed or checkpoint reaches them.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import (
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
)
from sqlalchemy.orm import Mapped, mapped_column, synonym

from app.models.base import Base, StudyStatus, enum_type, status_check, utcnow
from app.models.people import Member, OpenLink

#: Who answers: the person whose tree trained the agents, or others shown the instruction.
EVALUATOR_KINDS = ("advisor", "others")
#: What a pair shows of each agent.
STIMULUS_KINDS = ("still", "clip")


class Evaluation(Base):
    """Two groups of runs of one env (an experiment's advised and baseline runs, or any
    two), the question asked, and the design declared when it was created.

    ``status`` is a study's (:class:`StudyStatus`): ``preparing`` while the stills render,
    then ``ready`` (people can join) or ``failed`` (``error`` says why). ``clips_ready`` turns
    true once the clips, rendered after the stills, are there.
    """

    __tablename__ = "evaluations"
    __table_args__ = (
        status_check(StudyStatus),
        CheckConstraint("evaluator_kind IN ('advisor', 'others')", name="evaluator_kind"),
        CheckConstraint("stimulus IN ('still', 'clip')", name="stimulus"),
        CheckConstraint("pairs_per_evaluator >= 1 AND pairs_per_evaluator <= 200", name="pairs"),
        CheckConstraint("target_win_rate > 0.5 AND target_win_rate < 1", name="target"),
        CheckConstraint("evaluator_counter >= 0", name="evaluator_counter"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    env_id: Mapped[str] = mapped_column(String(100))
    #: The experiment it was made from (``None``: two groups of runs named directly).
    experiment_id: Mapped[int | None] = mapped_column(
        ForeignKey("experiments.id", ondelete="SET NULL"), default=None
    )
    evaluator_kind: Mapped[str] = mapped_column(String(16))
    #: The question or instruction each pair is asked under.
    question: Mapped[str] = mapped_column(Text)
    instructions: Mapped[str] = mapped_column(Text)
    #: The advisor (a participant whose tree trained the advised runs), when they answer.
    advisor_id: Mapped[int | None] = mapped_column(
        ForeignKey("participants.id", ondelete="SET NULL"), default=None
    )
    #: Whether the advisor's bracket is shown as a reminder (recorded with every answer too).
    show_bracket: Mapped[bool] = mapped_column(Boolean, default=False)
    stimulus: Mapped[str] = mapped_column(String(8))
    pairs_per_evaluator: Mapped[int] = mapped_column(Integer)
    #: Instructed gold pairs per evaluator ("choose the one with the marker"), placed among
    #: the real pairs and never counted in the result; the gate (``None``: none) leaves out an
    #: evaluator whose gold accuracy is clearly below it; practice pairs come first.
    gold_pairs: Mapped[int] = mapped_column(Integer, default=0)
    gold_gate: Mapped[float | None] = mapped_column(Float, default=None)
    practice_pairs: Mapped[int] = mapped_column(Integer, default=0)
    #: The advised agents' win rate the design is sized to detect (80% power).
    target_win_rate: Mapped[float] = mapped_column(Float)
    #: The design's size for ``target_win_rate`` at 80% power, simulated when it is prepared
    #: (:func:`engine.evaluation.power.answers_needed`): the fewest evaluators (``None``: no
    #: number of them reaches it with these runs), and the power reached there.
    needed_evaluators: Mapped[int | None] = mapped_column(Integer, default=None)
    design_power: Mapped[float | None] = mapped_column(Float, default=None)
    seed: Mapped[int] = mapped_column(BigInteger)
    #: Evaluators made so far: each new one takes the next index of the pair sequence (the
    #: database increments it atomically).
    evaluator_counter: Mapped[int] = mapped_column(Integer, default=0)
    status: Mapped[StudyStatus] = mapped_column(
        enum_type(StudyStatus), default=StudyStatus.PREPARING
    )
    clips_ready: Mapped[bool] = mapped_column(Boolean, default=False)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class EvaluationRun(Base):
    """A run's slot in an evaluation, its arm, and the checkpoint its stimuli come from."""

    __tablename__ = "evaluation_runs"

    evaluation_id: Mapped[int] = mapped_column(
        ForeignKey("evaluations.id", ondelete="CASCADE"), primary_key=True
    )
    slot: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), index=True)
    advised: Mapped[bool] = mapped_column(Boolean)
    step: Mapped[int] = mapped_column(BigInteger)


class EvaluationStimulus(Base):
    """One window of a slot's evaluation rollouts: its still, and its clip once rendered.

    Paths are relative to the evaluation's stimulus folder and named by content hash.
    """

    __tablename__ = "evaluation_stimuli"

    evaluation_id: Mapped[int] = mapped_column(
        ForeignKey("evaluations.id", ondelete="CASCADE"), primary_key=True
    )
    slot: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    window: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    still_path: Mapped[str] = mapped_column(String(255))
    clip_path: Mapped[str | None] = mapped_column(String(255), default=None)


class Evaluator(Member):
    """Someone answering an evaluation's pairs (a member of kind ``evaluation``)."""

    __tablename__ = "evaluators"
    __mapper_args__ = {"polymorphic_identity": "evaluation"}

    id: Mapped[int] = mapped_column(ForeignKey("members.id", ondelete="CASCADE"), primary_key=True)
    #: Their place in the evaluation's pair sequence (:func:`engine.evaluation.design`).
    sequence_index: Mapped[int] = mapped_column(Integer)
    excluded: Mapped[bool] = mapped_column(Boolean, default=False)
    exclusion_reason: Mapped[str | None] = mapped_column(String(200), default=None)
    #: Their evaluation (the member's collection).
    evaluation_id = synonym("collection_id")


class EvaluationPair(Base):
    """One pair an evaluator is asked: slots ``a`` and ``b`` (their windows), ``a`` on the
    left when ``a_left``. ``key`` is the pair's opaque id: its stimuli are served under it.

    An answer is written once, by ``UPDATE ... WHERE answered_at IS NULL``: ``winner`` is the
    slot chosen (``NULL`` with ``tie`` for "can't tell"); ``stimulus`` and ``reminder`` say
    what was shown when it was answered.
    """

    __tablename__ = "evaluation_pairs"
    __table_args__ = (
        CheckConstraint("a <> b", name="distinct_runs"),
        CheckConstraint("response_ms IS NULL OR response_ms >= 0", name="response_ms"),
    )

    evaluator_id: Mapped[int] = mapped_column(
        ForeignKey("evaluators.id", ondelete="CASCADE"), primary_key=True
    )
    position: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    key: Mapped[str] = mapped_column(String(32), unique=True)
    a: Mapped[int] = mapped_column(Integer)
    b: Mapped[int] = mapped_column(Integer)
    window_a: Mapped[int] = mapped_column(Integer)
    window_b: Mapped[int] = mapped_column(Integer)
    a_left: Mapped[bool] = mapped_column(Boolean)
    winner: Mapped[int | None] = mapped_column(Integer, default=None)
    tie: Mapped[bool] = mapped_column(Boolean, default=False)
    chose_left: Mapped[bool | None] = mapped_column(Boolean, default=None)
    response_ms: Mapped[int | None] = mapped_column(BigInteger, default=None)
    stimulus: Mapped[str | None] = mapped_column(String(8), default=None)
    reminder: Mapped[bool | None] = mapped_column(Boolean, default=None)
    #: A gold pair's marked slot, the right answer (``None``: a real pair, counted).
    gold_answer: Mapped[int | None] = mapped_column(Integer, default=None)
    answered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)


class EvaluationLink(OpenLink):
    """An evaluation's open link ``/e/<slug>``; it has no options of its own."""

    __mapper_args__ = {"polymorphic_identity": "evaluation"}

    #: The evaluation whose link this is.
    evaluation_id = synonym("collection_id")
