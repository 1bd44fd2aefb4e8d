"""The columns every person of a collection has (a study's participant, a survey's
respondent) and those of an open link (app/recruiting)."""

from __future__ import annotations

import hashlib
from datetime import datetime

from sqlalchemy import (
    JSON,
    Boolean,
    CheckConstraint,
    DateTime,
    Integer,
    String,
    Text,
)
from sqlalchemy.orm import Mapped, mapped_column, validates

from app.models.base import utcnow


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
