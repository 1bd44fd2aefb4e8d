"""The import rules between packages that ``docs/architecture.md`` draws, enforced.

Each rule reads every module's imports (``ast``, nothing is imported) and lists the ones that
break it, so a failure names the file and the import to move. The graph rules read the whole
import graph of a package: no circle, and the engine's layers.

Counted by hand: ``python -c "from tests.test_architecture import *; g = import_graph('engine');
print(cycles(g), upward_imports(g), cycles(import_graph('app')))"``.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Feature packages in the order a researcher's work goes through them: a feature's services
#: build on the ones before it, never on a later one (so the graph has no cycle). ``app.jobs``
#: is the runs feature's executor (its queue and executors), on the runs level. ``webhooks``
#: comes first: every feature writes its events to the webhooks' outbox, in its own
#: transactions, and the webhooks know no feature.
FEATURES = ("webhooks", "recruiting", "studies", "labelling", "runs", "surveys", "evaluations")
LEVEL = {**{f: i for i, f in enumerate(FEATURES)}, "jobs": FEATURES.index("runs")}
WEB_LIBRARIES = ("fastapi", "starlette", "sqlalchemy", "jinja2", "uvicorn", "alembic", "app")
#: Route modules: a feature's REST API and pages; only app.routes and other routes use them.
ROUTE_SUFFIXES = ("api", "pages", "downloads")


def module_name(path: Path, root: Path = ROOT) -> str:
    return ".".join(path.relative_to(root).with_suffix("").parts)


def imports(path: Path, root: Path = ROOT) -> Iterator[str]:
    """Every module ``path`` imports (``from a import b`` yields ``a`` and ``a.b``), in
    functions and under ``TYPE_CHECKING`` too (``ast.walk`` sees the whole file); a relative
    import is resolved against the file's package, ``path.parent`` (an ``__init__``'s too)."""
    package = module_name(path.parent, root).split(".")
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            yield module
            yield from (f"{module}.{alias.name}" for alias in node.names)


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
        found += [f"{source} imports {m}" for m in imports(path, root) if forbidden(source, m)]
    return found


def feature_of(module: str) -> str | None:
    """The feature package (or ``jobs``) ``module`` belongs to; ``app.jobs.settings`` (where
    runs live on disk) is on the floor, with ``app.core``."""
    parts = module.split(".")
    if parts[0] != "app" or len(parts) < 2 or module.startswith("app.jobs.settings"):
        return None
    return parts[1] if parts[1] in LEVEL else None


# --- the import graph: circles and layers ---------------------------------------------------

#: The engine's layers, lowest first, each a list of parts (a subpackage, a top-level module,
#: ``__init__`` for ``engine`` itself): a part imports its own layer and those below.
ENGINE_LAYERS = (
    # the floor: definitions every part shares, knowing no method
    "__init__ errors gym_types records pinned provenance ray_cluster mujoco_gl judges",
    # the MuJoCo world: a state made, restored and rendered, its reward and posture
    "envs rewards postures render",
    # the paper's method without an agent: the pure sampler, bracket, trees, advice, teachers
    "candidates practice bracket tournament preference_tree treefile advice teachers "
    "conformance agreement disagreement reliability pooling crowd_sim",
    # the verdict's statistics over judges' scores
    "verdict verdict_outcome verdict_power verdict_bracket verdict_specificity",
    "rl",  # agents: training with advice, and judging a checkpoint
    # needing a trained policy or runs: informative sampling, the pipeline (it samples in every
    # mode), policies trained elsewhere, the verdict over runs, the agent evaluation (its
    # stimuli are a checkpoint's rollouts)
    "informative pipeline policies verdict_runs evaluation",
    "validation",
)
ENGINE_LAYER = {part: i for i, layer in enumerate(ENGINE_LAYERS) for part in layer.split()}
#: ``source -> target`` imports of the engine allowed up a layer, with why (issue 43: at most 2).
ENGINE_UPWARD: dict[str, str] = {}
Graph = dict[str, set[str]]


def import_graph(package: str, root: Path = ROOT) -> Graph:
    """Module of ``package`` -> the modules of ``package`` it imports (see :func:`imports`):
    each imported name as the most specific module that exists (``from a import b`` is ``a.b``
    when that is a module, else ``a``); a package is its ``__init__``."""
    paths = {
        module_name(p.parent if p.name == "__init__.py" else p, root): p
        for p in (root / package.replace(".", "/")).rglob("*.py")
    }
    graph: Graph = {source: set() for source in paths}
    for source, path in paths.items():
        for name in imports(path, root):
            while name and name not in paths:
                name = name.rpartition(".")[0]
            graph[source] |= {name} - {"", source}
    return graph


def cycles(graph: Graph) -> list[tuple[str, ...]]:
    """Strongly connected components of over one module: each is one or more circles."""
    reach = {v: set(targets) for v, targets in graph.items()}
    for k in graph:  # Warshall: reach[v] grows to what v imports directly or not
        for v in graph:
            if k in reach[v]:
                reach[v] |= reach[k]
    found = {tuple(sorted(w for w in reach[v] if v in reach[w])) for v in graph}
    return sorted(c for c in found if len(c) > 1)


def engine_part(module: str) -> str:
    return module.split(".")[1] if "." in module else "__init__"


def upward_imports(graph: Graph) -> list[str]:
    """``source -> target`` for each engine import from a lower layer up to a higher one."""
    layer = {m: ENGINE_LAYER[engine_part(m)] for m in graph}
    return sorted(
        f"{s} -> {t}" for s, targets in graph.items() for t in targets if layer[t] > layer[s]
    )


def unnamed_upward(graph: Graph) -> list[str]:
    return [i for i in upward_imports(graph) if i not in ENGINE_UPWARD]


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


GRAPH_RULES: dict[str, tuple[str, Callable[[Graph], list[Any]]]] = {
    "the engine's imports make no circle": ("engine", cycles),
    "the engine imports up a layer only where named": ("engine", unnamed_upward),
    "the app's imports make no circle": ("app", cycles),
}


@pytest.mark.parametrize("rule", GRAPH_RULES)
def test_the_graph_rule_holds(rule: str) -> None:
    package, breaks = GRAPH_RULES[rule]
    assert not breaks(import_graph(package))


#: Files that break each graph rule: a circle closed relatively, under TYPE_CHECKING and in a
#: function; the pure sampler importing the agents.
PLANTED_GRAPHS = {
    "the engine's imports make no circle": {
        "engine/a.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import b",
        "engine/b.py": "def f() -> None:\n    from engine.a import f",
    },
    "the engine imports up a layer only where named": {
        "engine/candidates.py": "def f() -> None:\n    from engine.rl.returns import f",
        "engine/rl/returns.py": "",
    },
    "the app's imports make no circle": {"app/y.py": "import app.z", "app/z.py": "from . import y"},
}


@pytest.mark.parametrize("rule", GRAPH_RULES)
def test_each_graph_rule_sees_a_planted_break(rule: str, tmp_path: Path) -> None:
    package, breaks = GRAPH_RULES[rule]
    for where, text in PLANTED_GRAPHS[rule].items():
        (tmp_path / where).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / where).write_text(text + "\n")
    assert len(breaks(import_graph(package, tmp_path))) == 1


def test_every_engine_part_has_a_layer_and_few_go_up() -> None:
    graph = import_graph("engine")
    assert {engine_part(m) for m in graph} <= set(ENGINE_LAYER)
    assert len(ENGINE_UPWARD) <= 2 and set(ENGINE_UPWARD) <= set(upward_imports(graph))


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


def renamed_modules(root: Path = ROOT) -> list[str]:
    """Imports of a module of ``app/`` or ``engine/`` under a name that is not its own. Allowed:
    a feature's ``service`` under the feature's name (``studies``), and ``<feature>_<module>``
    where several features' modules of one name meet (``studies_api`` in ``app/routes.py``)."""
    found = []
    for path in sorted([*(root / "app").rglob("*.py"), *(root / "engine").rglob("*.py")]):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom) or not node.module:
                continue
            package = node.module.split(".")
            for alias in node.names:
                is_module = (root.joinpath(*package) / f"{alias.name}.py").is_file()
                allowed = (alias.name, f"{package[-1]}_{alias.name}")
                if alias.name == "service":
                    allowed += (package[-1],)
                if is_module and alias.asname not in (None, *allowed):
                    found.append(f"{path.relative_to(root)}: {alias.name} as {alias.asname}")
    return found


def test_modules_are_imported_under_their_own_names() -> None:
    assert renamed_modules() == []


def test_a_module_under_another_name_is_seen(tmp_path: Path) -> None:
    (tmp_path / "app" / "surveys").mkdir(parents=True)
    (tmp_path / "engine").mkdir()
    (tmp_path / "app" / "surveys" / "respond.py").write_text("")
    (tmp_path / "app" / "surveys" / "api.py").write_text(
        "from app.surveys import respond as survey_respond\n"
    )
    assert renamed_modules(tmp_path) == ["app/surveys/api.py: respond as survey_respond"]
