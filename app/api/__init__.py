"""The REST API: one router per resource under ``/api``, plus ``/healthz``."""

from __future__ import annotations

from fastapi import APIRouter

from app.api import (
    crowd,
    errors,
    experiments,
    health,
    matches,
    participants,
    run_advisors,
    runs,
    studies,
    survey_crowd,
    surveys,
)

api_router = APIRouter(prefix="/api", responses=errors.RESPONSES)
api_router.include_router(studies.router)
api_router.include_router(participants.router)
api_router.include_router(matches.router)
api_router.include_router(runs.router)
api_router.include_router(run_advisors.router)
api_router.include_router(experiments.router)
api_router.include_router(surveys.router)
api_router.include_router(crowd.router)
api_router.include_router(survey_crowd.router)

__all__ = ["api_router", "health"]
