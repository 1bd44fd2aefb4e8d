"""The REST API: one router per resource under ``/api``, plus ``/healthz``."""

from __future__ import annotations

from fastapi import APIRouter

from app.api import errors, health, matches, participants, runs, studies

api_router = APIRouter(prefix="/api", responses=errors.RESPONSES)
api_router.include_router(studies.router)
api_router.include_router(participants.router)
api_router.include_router(matches.router)
api_router.include_router(runs.router)

__all__ = ["api_router", "health"]
