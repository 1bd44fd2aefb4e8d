"""The people of every collection (a study's participants, a survey's respondents) in one
``members`` table, and every open link in one ``open_links`` table (app/recruiting).

Each kind keeps its few own columns in a child table (SQLAlchemy joined-table inheritance,
``polymorphic_on=collection_kind``): a participant's activity and exclusion
(``participants``), a respondent's stimulus and start (``survey_respondents``), a study
link's quality options (``study_link_options``). ``collection_id`` names a study or a survey
by ``collection_kind``; a reference to one of two tables cannot be a foreign key, and no
collection is ever deleted.
"""

from __future__ import annotations

import hashlib
from datetime import datetime

from sqlalchemy import (
    JSON,
    Boolean,
    CheckConstraint,
    DateTime,
    Index,
    Integer,
    String,
    Text,
)
from sqlalchemy.orm import Mapped, mapped_column, validates

from app.models.base import Base, utcnow

#: What a member or an open link belongs to: a study (bracket labelling), a survey, or an
#: agent evaluation.
COLLECTION_KINDS = ("study", "survey", "evaluation")
_KIND_CHECK = "collection_kind IN ('study', 'survey', 'evaluation')"


def token_digest(token: str) -> str:
    """SHA-256 of an invite token (hex): what members are looked up by."""
    return hashlib.sha256(token.encode()).hexdigest()


class Member(Base):
    """A member of a collection (a study's participant, a survey's respondent): who they are
    to us, an invite token, and who they are to a crowd platform.

    Requests are matched by ``token_hash`` and then the token itself is compared in
    constant time (:func:`app.recruiting.members.resolve`): an index lookup's timing
    can tell an attacker about the hash of their guess, never about a real token.
    """

    __tablename__ = "members"
    __table_args__ = (
        CheckConstraint(_KIND_CHECK, name="collection_kind"),
        Index("ix_members_collection", "collection_kind", "collection_id"),
        Index(
            "uq_members_collection_external_id",
            "collection_kind",
            "collection_id",
            "external_id",
            unique=True,
        ),
        Index(
            "uq_members_collection_join_key",
            "collection_kind",
            "collection_id",
            "join_key",
            unique=True,
        ),
    )
    __mapper_args__ = {"polymorphic_on": "collection_kind"}

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    collection_kind: Mapped[str] = mapped_column(String(16))
    collection_id: Mapped[int] = mapped_column(Integer)
    token: Mapped[str] = mapped_column(String(64), unique=True)
    token_hash: Mapped[str] = mapped_column(String(64), index=True, unique=True)
    name: Mapped[str | None] = mapped_column(String(200), default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: A crowd platform's id of the person (the collection's first external parameter,
    #: e.g. ``PROLIFIC_PID``): the same id coming back resumes this member.
    external_id: Mapped[str | None] = mapped_column(String(200), default=None)
    external_ids: Mapped[dict | None] = mapped_column(JSON, default=None)
    #: The consent form's one-time key: its second post (a double click, before the first
    #: answer set the cookie) resumes this member instead of taking a second seat.
    join_key: Mapped[str | None] = mapped_column(String(32), default=None)
    #: Whether they came through the open link (only they get its completion code).
    via_link: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Agreed to have their labels shared in a public dataset (under a salted hash of id).
    share_consent: Mapped[bool] = mapped_column(Boolean, default=False)
    #: When a member who joined through a timed link runs out of time (``None``: never).
    deadline_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: When they withdrew: their answers are kept, and left out of everything.
    withdrawn_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: When their seat on the open link was given back (set once: a seat is freed once).
    seat_freed_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)

    @validates("token")
    def _hash_token(self, _key: str, token: str) -> str:
        self.token_hash = token_digest(token)
        return token


class OpenLink(Base):
    """An open link (``/s/<slug>`` of a study, ``/q/<slug>`` of a survey) and its options.

    ``joined`` counts people created through the link; the database refuses more than
    ``max_participants`` (a CHECK), and a join increments it atomically. ``declines``
    counts declined consents (nothing else of a decline is stored).
    """

    __tablename__ = "open_links"
    __table_args__: tuple[object, ...] = (
        CheckConstraint(_KIND_CHECK, name="collection_kind"),
        CheckConstraint(
            "max_participants >= 1 AND joined >= 0 AND joined <= max_participants "
            "AND declines >= 0",
            name="counts",
        ),
        CheckConstraint(
            "time_limit_min IS NULL OR (time_limit_min >= 1 AND time_limit_min <= 10080)",
            name="time_limit",
        ),
        Index("uq_open_links_collection", "collection_kind", "collection_id", unique=True),
    )
    __mapper_args__ = {"polymorphic_on": "collection_kind"}

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    collection_kind: Mapped[str] = mapped_column(String(16))
    collection_id: Mapped[int] = mapped_column(Integer)
    slug: Mapped[str] = mapped_column(String(64), unique=True)
    enabled: Mapped[bool] = mapped_column(Boolean, default=False)
    max_participants: Mapped[int] = mapped_column(Integer)
    joined: Mapped[int] = mapped_column(Integer, default=0)
    declines: Mapped[int] = mapped_column(Integer, default=0)
    external_params: Mapped[list] = mapped_column(JSON)
    consent_text: Mapped[str | None] = mapped_column(Text, default=None)
    completion_code: Mapped[str | None] = mapped_column(String(100), default=None)
    redirect_url: Mapped[str | None] = mapped_column(String(500), default=None)
    #: Minutes a member has from joining to finishing (``None``: no limit); at most a week.
    time_limit_min: Mapped[int | None] = mapped_column(Integer, default=None)
    #: The code of a visitor who declines consent or a member who withdraws.
    decline_code: Mapped[str | None] = mapped_column(String(100), default=None)
