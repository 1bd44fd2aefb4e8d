"""Crowd recruiting (issue 14): a study's open link ``/s/<slug>``, external ids, consent,
and the completion code.

Each new visitor of an open link becomes a participant of their own. ``joined`` on the
study's :class:`CrowdSettings` row is incremented by one ``UPDATE ... WHERE joined <
max_participants`` in the same transaction that creates the participant, so concurrent
first visits never pass the maximum (the row lock on PostgreSQL, the single writer on
SQLite, and a CHECK constraint behind both). A visitor carrying the study's first external
parameter (``PROLIFIC_PID`` by default) who was seen before resumes that participant: the
``UNIQUE (study_id, external_id)`` constraint settles two first visits at once.
"""

from __future__ import annotations

import re
import secrets
from dataclasses import dataclass
from urllib.parse import urlsplit

from sqlalchemy import select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import writing
from app.models import CrowdSettings, Participant
from app.services.auth import new_token, participant_by_token
from app.services.errors import AuthError, ConflictError, NotFoundError
from app.services.participants import stage_participants
from app.services.studies import check_text, get_ready_study
from engine.errors import InputError

DEFAULT_EXTERNAL_PARAMS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
DEFAULT_SPEED_THRESHOLD_MS = 800
MAX_PARTICIPANTS = 100_000
MAX_EXTERNAL_CHARS = 200
_PARAM_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,63}")


class StudyFullError(ConflictError):
    """The open link reached its largest number of participants."""


@dataclass(frozen=True)
class CrowdOptions:
    """What the researcher sets for a study's open link and label-quality checks."""

    enabled: bool = False
    max_participants: int = 100
    external_params: tuple[str, ...] = DEFAULT_EXTERNAL_PARAMS
    consent_text: str | None = None
    completion_code: str | None = None
    redirect_url: str | None = None
    consistency_check: bool = False
    speed_threshold_ms: int = DEFAULT_SPEED_THRESHOLD_MS


def _check(options: CrowdOptions) -> None:
    if not 1 <= options.max_participants <= MAX_PARTICIPANTS:
        raise InputError(f"max_participants must be in 1..{MAX_PARTICIPANTS}")
    if not 1 <= len(options.external_params) <= 10 or not all(
        _PARAM_NAME.fullmatch(p) for p in options.external_params
    ):
        raise InputError("external_params must be 1..10 names of letters, digits and _")
    if len(set(options.external_params)) != len(options.external_params):
        raise InputError("external_params must not repeat a name")
    if options.redirect_url is not None and urlsplit(options.redirect_url).scheme not in (
        "http",
        "https",
    ):
        raise InputError("redirect_url must be an http(s) URL")
    if not 0 <= options.speed_threshold_ms <= 600_000:
        raise InputError("speed_threshold_ms must be in 0..600000")
    check_text(
        consent_text=options.consent_text,
        completion_code=options.completion_code,
        redirect_url=options.redirect_url,
    )


def crowd_settings(session: Session, *, study_id: int) -> CrowdSettings | None:
    """The study's open link and options, or ``None`` when never set."""
    return session.get(CrowdSettings, study_id)


def configure(session: Session, *, study_id: int, options: CrowdOptions) -> CrowdSettings:
    """Set a ready study's open link and options (the slug is made once and kept).

    Raises:
        InputError: a bad option, or a maximum below the participants already joined.
        NotFoundError, ConflictError: no such study, or it is not ready.
    """
    _check(options)
    get_ready_study(session, study_id=study_id)
    row = session.get(CrowdSettings, study_id)
    if row is None:
        row = CrowdSettings(study_id=study_id, slug=secrets.token_urlsafe(9), joined=0, declines=0)
    elif options.max_participants < row.joined:
        raise InputError(
            f"max_participants must be at least the {row.joined} participants who already joined"
        )
    for field, value in vars(options).items():
        setattr(row, field, list(value) if field == "external_params" else value)
    with writing(session):
        session.add(row)
    return row


def open_link(session: Session, *, slug: str) -> CrowdSettings:
    """The enabled open link ``slug``.

    Raises:
        NotFoundError: no such link, or the researcher closed it.
    """
    row = (
        session.scalar(select(CrowdSettings).where(CrowdSettings.slug == slug))
        if len(slug) <= 64
        else None
    )
    if row is None or not row.enabled:
        raise NotFoundError("This study link is not open. Check the link, or ask the researcher.")
    return row


def external_ids(link: CrowdSettings, query: dict[str, str]) -> dict[str, str]:
    """The link's external parameters found in ``query`` (trimmed, at most 200 chars).

    Raises:
        InputError: a value is too long or holds control characters.
    """
    found = {}
    for name in link.external_params:
        value = query.get(name, "").strip()
        if len(value) > MAX_EXTERNAL_CHARS or any(ord(c) < 32 for c in value):
            raise InputError(f"{name} must be at most {MAX_EXTERNAL_CHARS} printable characters")
        if value:
            found[name] = value
    return found


def returning(
    session: Session, *, link: CrowdSettings, ids: dict[str, str], token: str | None
) -> Participant | None:
    """The participant this visitor already is: by the first external id, or else by the
    invite cookie the browser holds for this study; ``None`` for a new visitor."""
    key = ids.get(link.external_params[0])
    if key is not None:
        return session.scalar(
            select(Participant).where(
                Participant.study_id == link.study_id, Participant.external_id == key
            )
        )
    if token:  # looked up by its hash and compared in constant time, as invite links are
        try:
            person = participant_by_token(session, token=token)
        except AuthError:
            return None
        if person.study_id == link.study_id:
            return person
    return None


def is_full(link: CrowdSettings) -> bool:
    return link.joined >= link.max_participants


def join(session: Session, *, link: CrowdSettings, ids: dict[str, str]) -> Participant:
    """A new participant for this visitor, or the one their first external id names.

    Raises:
        StudyFullError: the link has its largest number of participants already.
    """
    study = get_ready_study(session, study_id=link.study_id)
    key = ids.get(link.external_params[0])
    person = Participant(
        study_id=study.id, token=new_token(), external_id=key, external_ids=ids or None
    )
    try:
        with writing(session):
            taken = session.execute(
                update(CrowdSettings)
                .where(
                    CrowdSettings.study_id == study.id,
                    CrowdSettings.joined < CrowdSettings.max_participants,
                )
                .values(joined=CrowdSettings.joined + 1)
            ).rowcount  # type: ignore[attr-defined]
            if taken == 0:
                raise StudyFullError(
                    "This study is full: it has all the participants it "
                    "needs. Thank you for your interest."
                )
            stage_participants(session, study=study, people=[person])
    except IntegrityError:  # the same external id joined at the same moment: resume it
        existing = returning(session, link=link, ids=ids, token=None)
        if existing is None:
            raise
        return existing
    return person


def decline(session: Session, *, link: CrowdSettings) -> None:
    """Count a declined consent; nothing else about the visitor is stored."""
    with writing(session):
        session.execute(
            update(CrowdSettings)
            .where(CrowdSettings.study_id == link.study_id)
            .values(declines=CrowdSettings.declines + 1)
        )


def open_path(slug: str) -> str:
    return f"/s/{slug}"
