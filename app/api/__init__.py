"""The REST API: one router per resource under ``/api``, plus ``/healthz``."""

from __future__ import annotations

from fastapi import APIRouter

from app.api import health, matches, participants, studies

api_router = APIRouter(prefix="/api")
api_router.include_router(studies.router)
api_router.include_router(participants.router)
api_router.include_router(matches.router)

__all__ = ["api_router", "health"]
