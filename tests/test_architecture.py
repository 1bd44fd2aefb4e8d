"""The import rules between packages that ``docs/architecture.md`` draws, enforced.

Each rule reads every module's imports (``ast``, nothing is imported) and lists the ones that
break it, so a failure names the file and the import to move.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Feature packages in the order a researcher's work goes through them: a feature's services
#: build on the ones before it, never on a later one (so the graph has no cycle). ``app.jobs``
#: is the runs feature's executor (its queue and executors), on the runs level.
FEATURES = ("recruiting", "studies", "labelling", "runs", "surveys")
LEVEL = {**{f: i for i, f in enumerate(FEATURES)}, "jobs": FEATURES.index("runs")}
WEB_LIBRARIES = ("fastapi", "starlette", "sqlalchemy", "jinja2", "uvicorn", "alembic", "app")
#: Route modules: a feature's REST API and pages; only app.routes and other routes use them.
ROUTE_SUFFIXES = ("api", "pages", "downloads")


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def imports(path: Path) -> Iterator[str]:
    """Every module ``path`` imports (``from a import b`` yields ``a`` and ``a.b``)."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            yield from (f"{node.module}.{alias.name}" for alias in node.names)


def is_route(module: str) -> bool:
    parts = module.split(".")
    return (
        len(parts) == 3
        and parts[1] in FEATURES
        and any(parts[2] == s or parts[2].endswith(f"_{s}") for s in ROUTE_SUFFIXES)
    )


def violations(package: str, forbidden: Callable[[str, str], bool]) -> list[str]:
    """``source imports module`` for each import of ``package`` that ``forbidden`` names."""
    found = []
    for path in sorted((ROOT / package.replace(".", "/")).rglob("*.py")):
        source = module_name(path)
        found += [f"{source} imports {m}" for m in imports(path) if forbidden(source, m)]
    return found


def test_the_engine_imports_no_app_and_no_web_library() -> None:
    assert not violations("engine", lambda _, m: m.split(".")[0] in WEB_LIBRARIES)


def test_core_knows_no_feature_and_no_http() -> None:
    assert not violations(
        "app.core", lambda _, m: m.split(".")[:2] in [["app", f] for f in (*FEATURES, "http")]
    )


def test_http_knows_no_feature_but_the_member_lookup() -> None:
    def forbidden(_: str, m: str) -> bool:
        allowed = m in ("app.recruiting", "app.recruiting.members") or m.startswith(
            "app.recruiting.members."
        )
        return m.split(".")[:2] in [["app", f] for f in FEATURES] and not allowed

    assert not violations("app.http", forbidden)


@pytest.mark.parametrize("feature", FEATURES)
def test_services_import_no_http_and_no_route(feature: str) -> None:
    def forbidden(source: str, m: str) -> bool:
        return not is_route(source) and (m.startswith("app.http") or is_route(m))

    assert not violations(f"app.{feature}", forbidden)


def feature_of(module: str) -> str | None:
    """The feature package (or ``jobs``) ``module`` belongs to; ``app.jobs.settings`` (where
    runs live on disk) is on the floor, with ``app.core``."""
    parts = module.split(".")
    if parts[0] != "app" or len(parts) < 2 or module.startswith("app.jobs.settings"):
        return None
    return parts[1] if parts[1] in LEVEL else None


@pytest.mark.parametrize("feature", [*FEATURES, "jobs"])
def test_services_build_only_on_earlier_features(feature: str) -> None:
    def forbidden(source: str, m: str) -> bool:
        target = feature_of(m)
        return not is_route(source) and target is not None and LEVEL[target] > LEVEL[feature]

    assert not violations(f"app.{feature}", forbidden)


def test_only_routes_import_routes() -> None:
    def forbidden(source: str, m: str) -> bool:
        return is_route(m) and not is_route(source) and source not in ("app.routes",)

    assert not violations("app", forbidden)


def test_the_old_flat_layers_are_gone() -> None:
    assert not [p for p in ("services", "api", "web") if (ROOT / "app" / p).exists()]


def test_the_rules_see_a_break() -> None:
    """The checker itself: route modules are told from services, and imports are read."""
    assert is_route("app.studies.crowd_api") and is_route("app.runs.pages")
    assert not is_route("app.studies.service") and not is_route("app.recruiting.members")
    assert "app.http.deps" in set(imports(ROOT / "app" / "studies" / "api.py"))
    assert feature_of("app.runs.service") == "runs" and feature_of("app.jobs.queue") == "jobs"
    assert feature_of("app.jobs.settings") is None and feature_of("app.core.auth") is None
