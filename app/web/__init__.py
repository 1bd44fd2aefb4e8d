"""HTML pages (researcher pages, the participant's bracket UI), mounted by
:func:`app.main.create_app`.

The pages call the service layer (:mod:`app.services`) directly; their scripts (``static/js``)
use the REST API. No page has inline scripts (a ``script-src 'self'`` policy is sent), form
posts carry a CSRF token (:mod:`app.web.csrf`), and pages answer errors as HTML.
"""

from __future__ import annotations

from fastapi import APIRouter

from app.web import (
    auth_pages,
    crowd_pages,
    crowd_study_pages,
    downloads,
    experiment_pages,
    pair_pages,
    participant_pages,
    runs_pages,
    studies_pages,
    survey_crowd_pages,
    surveys_pages,
)

router = APIRouter()
router.include_router(auth_pages.router)
router.include_router(participant_pages.router)
router.include_router(pair_pages.router)
router.include_router(downloads.router)
router.include_router(studies_pages.router)
router.include_router(runs_pages.router)
router.include_router(experiment_pages.router)
router.include_router(surveys_pages.router)
router.include_router(crowd_pages.router)
router.include_router(crowd_study_pages.router)
router.include_router(survey_crowd_pages.router)

__all__ = ["router"]
