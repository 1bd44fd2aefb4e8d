"""Crowd recruiting for tree-reading surveys (issue 14): a survey's open link ``/q/<slug>``,
respondents' external ids, consent, and the completion code.

The seat count and options are :mod:`app.services.open_links`, as for studies. A visitor
carrying the survey's first external parameter (``PROLIFIC_PID`` by default) who was seen
before resumes that respondent: ``UNIQUE (survey_id, external_id)`` on
``survey_respondents`` settles two first visits at once.
"""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db import writing
from app.models import SurveyCrowdSettings, SurveyRespondent
from app.services import open_links
from app.services.auth import new_token
from app.services.members import SURVEY
from app.services.open_links import LinkFullError, LinkOptions
from app.services.surveys import get_survey


class SurveyFullError(LinkFullError):
    """The survey's open link reached its largest number of respondents."""


def crowd_settings(session: Session, *, survey_id: int) -> SurveyCrowdSettings | None:
    """The survey's open link and options, or ``None`` when never set."""
    return session.get(SurveyCrowdSettings, survey_id)


def configure(session: Session, *, survey_id: int, options: LinkOptions) -> SurveyCrowdSettings:
    """Set a survey's open link and options (the slug is made once and kept).

    Raises:
        InputError: a bad option, or a maximum below the respondents already joined.
        NotFoundError: no such survey.
    """
    open_links.check_options(options)
    get_survey(session, survey_id=survey_id)
    return open_links.save(
        session,
        session.get(SurveyCrowdSettings, survey_id),
        lambda: SurveyCrowdSettings(survey_id=survey_id),
        options,
    )


def open_link(session: Session, *, slug: str) -> SurveyCrowdSettings:
    """The open link ``slug``, open or closed; :class:`NotFoundError` if none."""
    return open_links.find(session, SurveyCrowdSettings, slug=slug, what="survey")


def external_ids(link: SurveyCrowdSettings, query: dict[str, str]) -> dict[str, str]:
    """The link's external parameters found in ``query`` (see :func:`open_links.external_ids`)."""
    return open_links.external_ids(link.external_params, query)


def returning(
    session: Session, *, link: SurveyCrowdSettings, ids: dict[str, str], token: str | None
) -> SurveyRespondent | None:
    """The respondent this visitor already is (:func:`open_links.returning`): by the
    respondent cookie the browser holds for this survey, or by the first external id with the
    per-attempt ids; ``None`` for a new visitor.

    Raises:
        AlreadyTookPartError: the external id joined before, from another browser.
    """
    return open_links.returning(
        session,
        SURVEY,
        owner_id=link.survey_id,
        params=link.external_params,
        ids=ids,
        token=token,
    )


def join(session: Session, *, link: SurveyCrowdSettings, ids: dict[str, str]) -> SurveyRespondent:
    """A new respondent for this visitor, or the one their first external id names.

    Raises:
        SurveyFullError: the link has its largest number of respondents already.
        LinkClosedError: the researcher closed the link.
    """
    open_links.check_open(link, what="survey")
    person = SurveyRespondent(
        survey_id=link.survey_id,
        token=new_token(),
        via_link=True,
        external_id=ids.get(link.external_params[0]),
        external_ids=ids or None,
    )
    full = SurveyFullError(
        "This survey is full: it has all the respondents it needs. Thank you for your interest."
    )
    try:
        with writing(session):
            owner = SurveyCrowdSettings.survey_id == link.survey_id
            open_links.take_seat(session, SurveyCrowdSettings, owner, full=full)
            session.add(person)
    except IntegrityError:  # the same external id joined at the same moment: resume it
        existing = returning(session, link=link, ids=ids, token=None)
        if existing is None:
            raise
        return existing
    return person


def decline(session: Session, *, link: SurveyCrowdSettings) -> None:
    """Count a declined consent; nothing else about the visitor is stored."""
    owner = SurveyCrowdSettings.survey_id == link.survey_id
    open_links.count_decline(session, SurveyCrowdSettings, owner)


def completed(session: Session, *, survey_id: int) -> int:
    """Respondents who came through the open link and answered every screen."""
    return (
        session.scalar(
            select(func.count(SurveyRespondent.id)).where(
                SurveyRespondent.survey_id == survey_id,
                SurveyRespondent.via_link.is_(True),
                SurveyRespondent.finished_at.is_not(None),
            )
        )
        or 0
    )


def completion(session: Session, *, respondent: SurveyRespondent) -> SurveyCrowdSettings | None:
    """The link whose completion code and redirect a finished open-link respondent gets;
    ``None`` before they finish, or for an invited respondent."""
    return open_links.completion(session, SurveyCrowdSettings, respondent.survey_id, respondent)


def open_path(slug: str) -> str:
    """The open link's path: ``/q/`` (questionnaire), apart from studies' ``/s/``."""
    return f"/q/{slug}"
