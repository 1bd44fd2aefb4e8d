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
#: is the runs feature's executor (its queue and executors), on the runs level. ``webhooks``
#: comes first: every feature writes its events to the webhooks' outbox, in its own
#: transactions, and the webhooks know no feature.
FEATURES = ("webhooks", "recruiting", "studies", "labelling", "runs", "surveys")
LEVEL = {**{f: i for i, f in enumerate(FEATURES)}, "jobs": FEATURES.index("runs")}
WEB_LIBRARIES = ("fastapi", "starlette", "sqlalchemy", "jinja2", "uvicorn", "alembic", "app")
#: Route modules: a feature's REST API and pages; only app.routes and other routes use them.
ROUTE_SUFFIXES = ("api", "pages", "downloads")


def module_name(path: Path, root: Path = ROOT) -> str:
    return ".".join(path.relative_to(root).with_suffix("").parts)


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


def violations(package: str, forbidden: Callable[[str, str], bool], root: Path = ROOT) -> list[str]:
    """``source imports module`` for each import of ``package`` that ``forbidden`` names."""
    found = []
    for path in sorted((root / package.replace(".", "/")).rglob("*.py")):
        source = module_name(path, root)
        found += [f"{source} imports {m}" for m in imports(path) if forbidden(source, m)]
    return found


def feature_of(module: str) -> str | None:
    """The feature package (or ``jobs``) ``module`` belongs to; ``app.jobs.settings`` (where
    runs live on disk) is on the floor, with ``app.core``."""
    parts = module.split(".")
    if parts[0] != "app" or len(parts) < 2 or module.startswith("app.jobs.settings"):
        return None
    return parts[1] if parts[1] in LEVEL else None


# --- the rules: forbidden(source module, imported module) -----------------------------------


def engine_rule(_: str, m: str) -> bool:
    return m.split(".")[0] in WEB_LIBRARIES


def core_rule(_: str, m: str) -> bool:
    return m.split(".")[:2] in [["app", f] for f in (*FEATURES, "http")]


def http_rule(_: str, m: str) -> bool:
    lookup = m in ("app.recruiting", "app.recruiting.members") or m.startswith(
        "app.recruiting.members."
    )
    return m.split(".")[:2] in [["app", f] for f in FEATURES] and not lookup


def service_rule(source: str, m: str) -> bool:
    """A feature's service (not its routes) importing the HTTP layer or a route."""
    service = source.split(".")[:2] in [["app", f] for f in FEATURES] and not is_route(source)
    return service and (m.startswith("app.http") or is_route(m))


def chain_rule(source: str, m: str) -> bool:
    """A service importing a feature after its own (``source`` names its feature)."""
    own, target = feature_of(source), feature_of(m)
    if is_route(source) or own is None or target is None:
        return False
    return LEVEL[target] > LEVEL[own]


def route_rule(source: str, m: str) -> bool:
    return is_route(m) and not is_route(source) and source != "app.routes"


RULES: dict[str, tuple[str, Callable[[str, str], bool]]] = {
    "the engine imports no app and no web library": ("engine", engine_rule),
    "core knows no feature and no http": ("app.core", core_rule),
    "http knows no feature but the member lookup": ("app.http", http_rule),
    "services import no http and no route": ("app", service_rule),
    "services build only on earlier features": ("app", chain_rule),
    "only routes import routes": ("app", route_rule),
}


@pytest.mark.parametrize("rule", RULES)
def test_the_rule_holds(rule: str) -> None:
    package, forbidden = RULES[rule]
    assert not violations(package, forbidden)


#: One import that breaks each rule, planted alone in a tree of its own.
PLANTED = {
    "the engine imports no app and no web library": ("engine/x.py", "import fastapi"),
    "core knows no feature and no http": ("app/core/x.py", "from app.http import deps"),
    "http knows no feature but the member lookup": (
        "app/http/x.py",
        "from app.studies import service",
    ),
    "services import no http and no route": ("app/runs/x.py", "from app.http import deps"),
    "services build only on earlier features": (
        "app/studies/x.py",
        "from app.runs import service",
    ),
    "only routes import routes": ("app/runs/x.py", "from app.studies import api"),
}


@pytest.mark.parametrize("rule", RULES)
def test_each_rule_sees_a_planted_break(rule: str, tmp_path: Path) -> None:
    """The checker itself: a tree holding one forbidden import is refused by its rule."""
    package, forbidden = RULES[rule]
    where, line = PLANTED[rule]
    (tmp_path / where).parent.mkdir(parents=True)
    (tmp_path / where).write_text(line + "\n")
    found = violations(package, forbidden, tmp_path)
    assert found and all(v.startswith(where.removesuffix(".py").replace("/", ".")) for v in found)


def test_the_old_flat_layers_are_gone() -> None:
    assert not [p for p in ("services", "api", "web") if (ROOT / "app" / p).exists()]


def test_routes_and_features_are_told_apart() -> None:
    assert is_route("app.studies.crowd_api") and is_route("app.runs.pages")
    assert not is_route("app.studies.service") and not is_route("app.recruiting.members")
    assert "app.http.deps" in set(imports(ROOT / "app" / "studies" / "api.py"))
    assert feature_of("app.runs.service") == "runs" and feature_of("app.jobs.queue") == "jobs"
    assert feature_of("app.jobs.settings") is None and feature_of("app.core.auth") is None
    assert feature_of("app.webhooks.outbox") == "webhooks" and is_route("app.webhooks.pages")


def test_the_webhooks_know_no_feature(tmp_path: Path) -> None:
    """The outbox is below every feature (each writes its events there): a webhooks service
    that imports a feature is refused, and a feature writing to the outbox is not."""
    (tmp_path / "app" / "webhooks").mkdir(parents=True)
    (tmp_path / "app" / "recruiting").mkdir(parents=True)
    (tmp_path / "app" / "webhooks" / "x.py").write_text("from app.recruiting import links\n")
    (tmp_path / "app" / "recruiting" / "y.py").write_text("from app.webhooks import outbox\n")
    found = violations("app", chain_rule, tmp_path)
    assert found == [
        "app.webhooks.x imports app.recruiting",
        "app.webhooks.x imports app.recruiting.links",
    ]
