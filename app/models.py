"""Database tables (SQLAlchemy 2 declarative). The schema itself comes from ``migrations/``.

A study owns its candidates (ids ``0 .. N-1``, as in ``acv.tree/1``) and its first-round
bracket; each participant plays the whole bracket on their own. A match row exists once both
of its players are known, and holds at most one label: ``labels.match_id`` is UNIQUE, so the
database itself refuses a second decision of a match.
"""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime
from enum import StrEnum

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    CheckConstraint,
    DateTime,
    Enum,
    Float,
    ForeignKey,
    ForeignKeyConstraint,
    Index,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, validates

from engine.rl.config import Algo
from engine.teachers import Teacher


class StudyStatus(StrEnum):
    """Where a study stands: its candidates are being prepared, ready, or failed."""

    PREPARING = "preparing"
    READY = "ready"
    FAILED = "failed"


class RunStatus(StrEnum):
    """Where a training run stands (``queued`` -> ``running`` -> one of the last four)."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"
    INTERRUPTED = "interrupted"


class ExperimentRole(StrEnum):
    """A run's part in an experiment: trained with the advice, or a no-advice baseline that
    the verdict compares with (``baseline``) or that picks the contested matches (``pilot``)."""

    ADVISED = "advised"
    BASELINE = "baseline"
    PILOT = "pilot"


STUDY_STATUSES: tuple[str, ...] = tuple(s.value for s in StudyStatus)
RUN_STATUSES: tuple[str, ...] = tuple(s.value for s in RunStatus)


def enum_type(members: type[StrEnum], length: int = 16) -> Enum:
    """A ``VARCHAR(length)`` column of ``members``' values, read back as members.

    Not a database enum type (``native_enum=False``) and no constraint of its own, so the
    schema stays the migrations' (``status`` and ``role`` have CHECK constraints). A value
    that is no member is refused when written (``validate_strings``): loading one would fail.
    """
    return Enum(
        members,
        native_enum=False,
        create_constraint=False,
        validate_strings=True,
        length=length,
        values_callable=lambda enum: [member.value for member in enum],
    )


def status_check(statuses: type[StrEnum]) -> CheckConstraint:
    """``status IN (...)`` over every member of ``statuses``."""
    listed = ", ".join(f"'{s.value}'" for s in statuses)
    return CheckConstraint(f"status IN ({listed})", name="status")


#: Deterministic constraint names, so that migrations can refer to them on every backend.
NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_N_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utcnow() -> datetime:
    return datetime.now(UTC)


def as_utc(moment: datetime) -> datetime:
    """A stored time as an aware UTC datetime (SQLite returns them naive)."""
    return moment if moment.tzinfo else moment.replace(tzinfo=UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


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


def token_digest(token: str) -> str:
    """SHA-256 of an invite token (hex): what participants are looked up by."""
    return hashlib.sha256(token.encode()).hexdigest()


class MemberColumns:
    """The columns every member of a collection has (a study's participant, a survey's
    respondent): who they are to us, an invite token, and who they are to a crowd platform.

    Requests are matched by ``token_hash`` and then the token itself is compared in
    constant time (:func:`app.recruiting.members.resolve`): an index lookup's timing
    can tell an attacker about the hash of their guess, never about a real token.
    """

    id: Mapped[int] = mapped_column(Integer, primary_key=True, sort_order=-1)
    token: Mapped[str] = mapped_column(String(64), unique=True)
    token_hash: Mapped[str] = mapped_column(String(64), index=True, unique=True)
    name: Mapped[str | None] = mapped_column(String(200), default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: A crowd platform's id of the person (the collection's first external parameter,
    #: e.g. ``PROLIFIC_PID``): the same id coming back resumes this member.
    external_id: Mapped[str | None] = mapped_column(String(200), default=None)
    external_ids: Mapped[dict | None] = mapped_column(JSON, default=None)
    #: Whether they came through the open link (only they get its completion code).
    via_link: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Agreed to have their labels shared in a public dataset (under a salted hash of id).
    share_consent: Mapped[bool] = mapped_column(Boolean, default=False)

    @validates("token")
    def _hash_token(self, _key: str, token: str) -> str:
        self.token_hash = token_digest(token)
        return token


class Participant(MemberColumns, Base):
    """Someone labelling a study's bracket, known only by their invite token."""

    __tablename__ = "participants"
    __table_args__ = (
        Index("uq_participants_study_external_id", "study_id", "external_id", unique=True),
    )

    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    last_active_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: Left out of pooling and exports (by the researcher, or by the gold gate when it
    #: excludes); their labels are kept.
    excluded: Mapped[bool] = mapped_column(Boolean, default=False)
    exclusion_reason: Mapped[str | None] = mapped_column(String(200), default=None)


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


class OpenLink:
    """The columns of an open link (``/s/<slug>`` of a study, ``/q/<slug>`` of a survey).

    ``joined`` counts people created through the link; the database refuses more than
    ``max_participants`` (a CHECK on each table), and a join increments it atomically.
    ``declines`` counts declined consents (nothing else of a decline is stored).
    """

    slug: Mapped[str] = mapped_column(String(64), unique=True)
    enabled: Mapped[bool] = mapped_column(Boolean, default=False)
    max_participants: Mapped[int] = mapped_column(Integer)
    joined: Mapped[int] = mapped_column(Integer, default=0)
    declines: Mapped[int] = mapped_column(Integer, default=0)
    external_params: Mapped[list] = mapped_column(JSON)
    consent_text: Mapped[str | None] = mapped_column(Text, default=None)
    completion_code: Mapped[str | None] = mapped_column(String(100), default=None)
    redirect_url: Mapped[str | None] = mapped_column(String(500), default=None)


def open_link_counts() -> CheckConstraint:
    return CheckConstraint(
        "max_participants >= 1 AND joined >= 0 AND joined <= max_participants AND declines >= 0",
        name="counts",
    )


class CrowdSettings(OpenLink, Base):
    """A study's open link ``/s/<slug>`` and its crowd options (app.studies.crowd)."""

    __tablename__ = "crowd_settings"
    __table_args__ = (
        open_link_counts(),
        CheckConstraint("speed_threshold_ms >= 0", name="speed"),
    )

    study_id: Mapped[int] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), primary_key=True
    )
    consistency_check: Mapped[bool] = mapped_column(Boolean, default=False)
    speed_threshold_ms: Mapped[int] = mapped_column(Integer, default=800)
    #: The qualification gate: a participant whose gold accuracy's upper confidence bound is
    #: below it is flagged (``None``: no gate).
    gold_gate: Mapped[float | None] = mapped_column(Float, default=None)
    #: Whether the gate also excludes the participants it flags.
    gate_excludes: Mapped[bool] = mapped_column(Boolean, default=False)


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


class Run(Base):
    """A training run of a study, and its place in the job queue (see :mod:`app.jobs`).

    ``advice`` is the ``acv.tree/1`` document the run trains with (a finished participant's
    tree or a simulated teacher's, frozen when the run is created) or NULL. A run on pooled
    advice lists its participants' trees in ``advice_pool`` (``{"participant_id", "tree"}``,
    by participant id), has no ``participant_id`` nor ``teacher``, and its ``advice`` is the
    pooled verdict (:func:`engine.pooling.pooled_tree`). ``config`` is the
    whole :class:`engine.rl.config.TrainConfig`. ``worker`` names the worker that claimed the
    run (``host:pid:nonce``) and ``heartbeat_at`` when it last showed signs of life.
    """

    __tablename__ = "runs"
    __table_args__ = (
        status_check(RunStatus),
        CheckConstraint("participant_id IS NULL OR teacher IS NULL", name="one_advice_source"),
        CheckConstraint("timesteps > 0 AND n_envs > 0 AND progress >= 0", name="budget"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    participant_id: Mapped[int | None] = mapped_column(
        ForeignKey("participants.id", ondelete="CASCADE"), default=None
    )
    teacher: Mapped[Teacher | None] = mapped_column(enum_type(Teacher), default=None)
    algo: Mapped[Algo] = mapped_column(enum_type(Algo))
    timesteps: Mapped[int] = mapped_column(BigInteger)
    seed: Mapped[int] = mapped_column(BigInteger)
    n_envs: Mapped[int] = mapped_column(Integer)
    config: Mapped[dict] = mapped_column(JSON)
    advice: Mapped[dict | None] = mapped_column(JSON, default=None)
    advice_pool: Mapped[list | None] = mapped_column(JSON, default=None)
    status: Mapped[RunStatus] = mapped_column(
        enum_type(RunStatus), default=RunStatus.QUEUED, index=True
    )
    resume: Mapped[bool] = mapped_column(Boolean, default=False)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    executor: Mapped[str | None] = mapped_column(String(16), default=None)
    worker: Mapped[str | None] = mapped_column(String(200), default=None)
    progress: Mapped[int] = mapped_column(BigInteger, default=0)
    metrics: Mapped[dict | None] = mapped_column(JSON, default=None)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)


class Experiment(Base):
    """One advice source, algorithm, env and budget trained on several seeds, with its
    matched no-advice baseline (the same seeds) and pilot runs (seeds of their own).

    ``spec`` is the request its advised runs were created from, less the seed (``/api/runs``'s
    body); ``seeds`` the evaluation seeds, ``pilot_seeds`` the pilot runs' seeds (disjoint).
    Its runs are listed in ``experiment_runs``; a baseline or pilot run may be shared by
    several experiments (the same study, config and seed).
    """

    __tablename__ = "experiments"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("studies.id", ondelete="CASCADE"), index=True)
    spec: Mapped[dict] = mapped_column(JSON)
    seeds: Mapped[list] = mapped_column(JSON)
    pilot_seeds: Mapped[list] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class ExperimentRun(Base):
    """A run's part in an experiment (:class:`ExperimentRole`)."""

    __tablename__ = "experiment_runs"
    __table_args__ = (
        CheckConstraint(
            "role IN (" + ", ".join(f"'{r.value}'" for r in ExperimentRole) + ")", name="role"
        ),
    )

    experiment_id: Mapped[int] = mapped_column(
        ForeignKey("experiments.id", ondelete="CASCADE"), primary_key=True
    )
    run_id: Mapped[int] = mapped_column(
        ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True, index=True
    )
    role: Mapped[ExperimentRole] = mapped_column(enum_type(ExperimentRole, length=8))


class CheckpointArtefact(Base):
    """What the executor computed at one checkpoint of a run; written once, then only read.

    ``payload`` is :meth:`engine.rl.report.CheckpointReport.to_json`: the Agent Preference
    Tree of every judge, its conformance to the run's advice tree, and the per-candidate table.
    A checkpoint without a row is still being computed ("pending").
    """

    __tablename__ = "checkpoint_artefacts"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    step: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    payload: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class RunMetric(Base):
    """One metrics row of a run (one per PPO update), as its executor reported it: scalars
    only (:func:`app.runs.run_state.scalar_metrics`). Pages and the API read these, never the
    run folder's ``metrics.jsonl``."""

    __tablename__ = "run_metrics"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    timesteps: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    row: Mapped[dict] = mapped_column(JSON)


class RunCheckpoint(Base):
    """A checkpoint a run's executor saved (its file is ``checkpoints/step_<step>.pt`` in the
    run folder, which only executors read)."""

    __tablename__ = "run_checkpoints"

    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id", ondelete="CASCADE"), primary_key=True)
    step: Mapped[int] = mapped_column(BigInteger, primary_key=True, autoincrement=False)
    saved_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


# --- Tree-reading surveys (the paper's user study; app.surveys.service) ---------------------

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


class SurveyRespondent(MemberColumns, Base):
    """Someone answering a survey, known only by their invite token (as a participant).

    ``started_at`` is set once, by whichever request first plans their screens (an atomic
    ``UPDATE ... WHERE started_at IS NULL``); ``stimulus_id`` is their round-robin stimulus.
    """

    __tablename__ = "survey_respondents"
    __table_args__ = (
        Index("uq_survey_respondents_survey_external_id", "survey_id", "external_id", unique=True),
    )

    survey_id: Mapped[int] = mapped_column(ForeignKey("surveys.id", ondelete="CASCADE"), index=True)
    stimulus_id: Mapped[int | None] = mapped_column(
        ForeignKey("survey_stimuli.id", ondelete="CASCADE"), default=None
    )
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)


class SurveyCrowdSettings(OpenLink, Base):
    """A survey's open link ``/q/<slug>`` (app.surveys.crowd)."""

    __tablename__ = "survey_crowd_settings"
    __table_args__ = (open_link_counts(),)

    survey_id: Mapped[int] = mapped_column(
        ForeignKey("surveys.id", ondelete="CASCADE"), primary_key=True
    )


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


class Webhook(Base):
    """A URL a study's or a survey's events are POSTed to, signed with ``secret`` (Standard
    Webhooks: ``whsec_`` and base64 key bytes)."""

    __tablename__ = "webhooks"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    study_id: Mapped[int | None] = mapped_column(
        ForeignKey("studies.id", ondelete="CASCADE"), index=True, default=None
    )
    survey_id: Mapped[int | None] = mapped_column(
        ForeignKey("surveys.id", ondelete="CASCADE"), index=True, default=None
    )
    url: Mapped[str] = mapped_column(String(2000))
    secret: Mapped[str] = mapped_column(String(100))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class WebhookEvent(Base):
    """The outbox: an event for one webhook, written in the transaction of the change it
    reports; delivered at least once (``delivered_at``), deduplicated by ``event_id``."""

    __tablename__ = "webhook_events"
    __table_args__ = (Index("ix_webhook_events_due", "delivered_at", "next_attempt_at"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    webhook_id: Mapped[int] = mapped_column(ForeignKey("webhooks.id", ondelete="CASCADE"))
    event_id: Mapped[str] = mapped_column(String(64), unique=True)
    type: Mapped[str] = mapped_column(String(64))
    payload: Mapped[dict] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    next_attempt_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    delivered_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)


class WebhookAttempt(Base):
    """One delivery attempt of an event: the receiver's status, or the error."""

    __tablename__ = "webhook_attempts"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    event_id: Mapped[int] = mapped_column(
        ForeignKey("webhook_events.id", ondelete="CASCADE"), index=True
    )
    attempted_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    status_code: Mapped[int | None] = mapped_column(Integer, default=None)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    duration_ms: Mapped[int] = mapped_column(Integer)
