"""``/healthz``: the app is up and its database answers."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter
from pydantic import BaseModel
from sqlalchemy import text

from app.http.deps import SessionDep
from app.http.errors import RESPONSES


class HealthOut(BaseModel):
    status: Literal["ok"]


router = APIRouter(tags=["health"], responses={503: RESPONSES[503]})


@router.get("/healthz")
def healthz(session: SessionDep) -> HealthOut:
    session.execute(text("SELECT 1"))
    return HealthOut(status="ok")
