"""Invite tokens stay out of the access log: ``/p/<token>`` is logged as ``/p/***`` (and a
survey respondent's ``/r/<token>`` and an evaluator's ``/v/<token>`` alike; the open links of
a study ``/s/<slug>``, a survey ``/q/<slug>`` and an evaluation ``/e/<slug>`` and their query
strings, which carry crowd platforms' participant ids, as ``/s/***``, ``/q/***``, ``/e/***``).

An invite token is a participant's only credential, and access logs are kept and shared far
more widely (journald, docker logs) than the database. uvicorn logs each request on the
``uvicorn.access`` logger with the path as the third argument of its record.
"""

from __future__ import annotations

import logging
import re

ACCESS_LOGGER = "uvicorn.access"
_INVITE_PATH = re.compile(r"^/([prv])/[^/?#]+|^/([sqe])/[^#]*")  # invite and open links


def mask_invite_tokens(path: str) -> str:
    """``path`` with the token of an invite link replaced by ``***``."""
    return _INVITE_PATH.sub(lambda m: f"/{m.group(1) or m.group(2)}/***", path, count=1)


class MaskInviteTokens(logging.Filter):
    """Rewrites the path argument of uvicorn's access records; drops nothing."""

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if isinstance(args, tuple) and len(args) >= 3 and isinstance(args[2], str):
            record.args = (*args[:2], mask_invite_tokens(args[2]), *args[3:])
        return True


def install_access_log_filter() -> None:
    """Add :class:`MaskInviteTokens` to uvicorn's access logger, once per process (the
    logger keeps its filters when uvicorn configures logging afterwards)."""
    logger = logging.getLogger(ACCESS_LOGGER)
    if not any(isinstance(f, MaskInviteTokens) for f in logger.filters):
        logger.addFilter(MaskInviteTokens())
