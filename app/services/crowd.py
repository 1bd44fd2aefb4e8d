"""Crowd recruiting (issue 14): a study's open link ``/s/<slug>``, external ids, consent,
and the completion code.

Each new visitor of an open link becomes a participant of their own; the seat count and the
options are :mod:`app.services.open_links` (shared with surveys). A visitor carrying the
study's first external parameter (``PROLIFIC_PID`` by default) who was seen before resumes
that participant: the ``UNIQUE (study_id, external_id)`` constraint settles two first visits
at once.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import writing
from app.models import CrowdSettings, Participant
from app.services import open_links
from app.services.auth import new_token
from app.services.members import STUDY
from app.services.open_links import (
    DEFAULT_EXTERNAL_PARAMS,
    MAX_PARTICIPANTS,
    LinkFullError,
    LinkOptions,
    is_full,
)
from app.services.participants import stage_participants
from app.services.studies import get_ready_study
from engine.errors import InputError

__all__ = ["DEFAULT_EXTERNAL_PARAMS", "MAX_PARTICIPANTS", "StudyFullError", "is_full"]
DEFAULT_SPEED_THRESHOLD_MS = 800


class StudyFullError(LinkFullError):
    """The open link reached its largest number of participants."""


@dataclass(frozen=True)
class CrowdOptions(LinkOptions):
    """What the researcher sets for a study's open link and label-quality checks."""

    consistency_check: bool = False
    speed_threshold_ms: int = DEFAULT_SPEED_THRESHOLD_MS


def _check(options: CrowdOptions) -> None:
    open_links.check_options(options)
    if not 0 <= options.speed_threshold_ms <= 600_000:
        raise InputError("speed_threshold_ms must be in 0..600000")


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
    return open_links.save(
        session,
        session.get(CrowdSettings, study_id),
        lambda: CrowdSettings(study_id=study_id),
        options,
    )


def open_link(session: Session, *, slug: str) -> CrowdSettings:
    """The open link ``slug``, open or closed (:func:`open_links.find`).

    Raises:
        NotFoundError: no such link.
    """
    return open_links.find(session, CrowdSettings, slug=slug, what="study")


def external_ids(link: CrowdSettings, query: dict[str, str]) -> dict[str, str]:
    """The link's external parameters found in ``query`` (see :func:`open_links.external_ids`)."""
    return open_links.external_ids(link.external_params, query)


def returning(
    session: Session, *, link: CrowdSettings, ids: dict[str, str], token: str | None
) -> Participant | None:
    """The participant this visitor already is (:func:`open_links.returning`): by the invite
    cookie the browser holds for this study, or by the first external id with the per-attempt
    ids; ``None`` for a new visitor.

    Raises:
        AlreadyTookPartError: the external id joined before, from another browser.
    """
    return open_links.returning(
        session,
        STUDY,
        owner_id=link.study_id,
        params=link.external_params,
        ids=ids,
        token=token,
    )


def join(session: Session, *, link: CrowdSettings, ids: dict[str, str]) -> Participant:
    """A new participant for this visitor, or the one their first external id names.

    Raises:
        StudyFullError: the link has its largest number of participants already.
        LinkClosedError: the researcher closed the link.
    """
    open_links.check_open(link, what="study")
    study = get_ready_study(session, study_id=link.study_id)
    key = ids.get(link.external_params[0])
    person = Participant(
        study_id=study.id,
        token=new_token(),
        external_id=key,
        external_ids=ids or None,
        via_link=True,
    )
    try:
        with writing(session):
            open_links.take_seat(
                session,
                CrowdSettings,
                CrowdSettings.study_id == study.id,
                full=StudyFullError(
                    "This study is full: it has all the participants it needs. "
                    "Thank you for your interest."
                ),
            )
            stage_participants(session, study=study, people=[person])
    except IntegrityError:  # the same external id joined at the same moment: resume it
        existing = returning(session, link=link, ids=ids, token=None)
        if existing is None:
            raise
        return existing
    return person


def completion(session: Session, *, participant: Participant) -> CrowdSettings | None:
    """The link whose completion code and redirect a finished open-link participant gets;
    ``None`` before they finish, or for an invited participant."""
    return open_links.completion(session, CrowdSettings, participant.study_id, participant)


def decline(session: Session, *, link: CrowdSettings) -> None:
    """Count a declined consent; nothing else about the visitor is stored."""
    open_links.count_decline(session, CrowdSettings, CrowdSettings.study_id == link.study_id)


def open_path(slug: str) -> str:
    return f"/s/{slug}"
