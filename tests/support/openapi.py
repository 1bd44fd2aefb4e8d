"""The API's OpenAPI document for test collection, and the operations that take JSON."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fastapi import FastAPI

from app.http.errors import install
from app.routes import api_router


def api_openapi() -> dict[str, Any]:
    """The API's schema, built from its routers alone (collection needs no database)."""
    app = FastAPI()
    install(app)
    app.include_router(api_router)
    return app.openapi()


@dataclass(frozen=True)
class JsonOperation:
    """An operation with an ``application/json`` request body."""

    method: str
    path: str
    schema: dict[str, Any]  # the body's schema
    schemes: tuple[str, ...]  # the security schemes whose credentials it takes

    def __str__(self) -> str:
        return f"{self.method} {self.path}"


def json_operations(openapi: dict[str, Any]) -> list[JsonOperation]:
    """Every operation of ``openapi`` whose request body is JSON."""
    return [
        JsonOperation(
            method.upper(),
            path,
            body["schema"],
            tuple(name for requirement in operation.get("security", []) for name in requirement),
        )
        for path, operations in openapi["paths"].items()
        for method, operation in operations.items()
        if (body := operation.get("requestBody", {}).get("content", {}).get("application/json"))
    ]
