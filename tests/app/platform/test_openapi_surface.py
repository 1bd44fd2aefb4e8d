"""The REST API keeps every path, operation and field it had (issue 26's refactor must not
drop one): the surface recorded in ``openapi_surface.json`` is a subset of today's.

After a deliberate change to the API, write the file again with
``python -m tests.app.platform.test_openapi_surface`` and say why in the commit.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fastapi import FastAPI

from app.main import create_app
from app.settings import Settings
from tests.support.openapi import api_openapi
from tests.support.web import ADMIN_TOKEN

SURFACE = Path(__file__).with_name("openapi_surface.json")


def surface(openapi: dict[str, Any]) -> dict[str, list[str]]:
    """Each operation with its parameters, each operation id (what generated clients name
    their methods by), and each schema with its fields, as sorted lists."""
    operations = [
        (path, method, op) for path, ops in openapi["paths"].items() for method, op in ops.items()
    ]
    found = {
        f"{method.upper()} {path}": sorted(p["name"] for p in op.get("parameters", []))
        for path, method, op in operations
    }
    found |= {f"operationId {op['operationId']}": [] for _, _, op in operations}
    for name, schema in openapi["components"]["schemas"].items():
        found[f"schema {name}"] = sorted(schema.get("properties", {}))
    return found


def test_every_path_operation_and_field_is_kept() -> None:
    recorded = json.loads(SURFACE.read_text())
    now = surface(api_openapi())
    missing = {k: v for k, v in recorded.items() if k not in now}
    assert not missing, f"gone from the API: {sorted(missing)}"
    dropped = {k: sorted(set(v) - set(now[k])) for k, v in recorded.items() if set(v) - set(now[k])}
    assert not dropped, f"fields gone from the API: {dropped}"


def test_apps_share_one_document_the_one_fastapi_generates_for_each(tmp_path: Path) -> None:
    """``create_app`` generates the document once per process (``app.main._shared_openapi``):
    an app with other settings (a trusted proxy, several processes) has the same routes, so
    the document FastAPI generates for it alone is the shared one."""
    plain = create_app(Settings(data_dir=tmp_path / "a", admin_token=ADMIN_TOKEN))
    proxied = Settings(
        data_dir=tmp_path / "b", admin_token=ADMIN_TOKEN, forwarded_allow_ips="10.0.0.1"
    )
    other = create_app(proxied, background=False, processes=2)
    assert other.openapi() is plain.openapi()
    assert FastAPI.openapi(other) == plain.openapi()


if __name__ == "__main__":
    SURFACE.write_text(json.dumps(surface(api_openapi()), indent=1, sort_keys=True) + "\n")
