"""Failed researcher logins, shared by every server process and host (app/http/lockouts)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import DateTime, Index, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from app.models.base import Base


class LoginFailure(Base):
    """A wrong researcher credential from ``address`` (the client's, or the one a trusted
    proxy forwarded) at ``at``: kept while it is in the lockout's moving window, then
    pruned (:class:`app.http.lockouts.DatabaseFailures`)."""

    __tablename__ = "login_failures"
    __table_args__ = (Index("ix_login_failures_address", "address", "at"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    address: Mapped[str] = mapped_column(String(200))
    at: Mapped[datetime] = mapped_column(DateTime(timezone=True), index=True)
