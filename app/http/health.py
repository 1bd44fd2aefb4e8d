"""``/healthz``: the app is up and its database answers."""

from __future__ import annotations

from fastapi import APIRouter
from sqlalchemy import text

from app.http.deps import SessionDep
from app.http.errors import RESPONSES
from app.studies.schemas import HealthOut

router = APIRouter(tags=["health"], responses={503: RESPONSES[503]})


@router.get("/healthz")
def healthz(session: SessionDep) -> HealthOut:
    session.execute(text("SELECT 1"))
    return HealthOut(status="ok")
