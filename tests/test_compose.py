"""``docker-compose.yml`` and ``Dockerfile`` refer only to things that exist.

No Docker engine here, so this reads them: every service built from this repository runs a
real console script, subcommand, module or Alembic configuration (also inside a ``sh -c``
script); its environment holds only variables the app's settings read; volumes, dependencies
and URLs point at declared volumes and services; migrations run once before the web and the
worker start; the worker joins the Ray cluster it submits to; only the web is published on
every interface (never Ray's dashboard, whose Jobs API runs any code unauthenticated).
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
import shlex
import tomllib
from configparser import ConfigParser
from pathlib import Path
from typing import Any

import pytest
import typer
import yaml
from pydantic import AliasChoices
from pydantic_settings import BaseSettings

from app.cli import cli
from app.jobs.settings import JobSettings
from app.settings import Settings

REPO = Path(__file__).resolve().parents[1]
COMPOSE = yaml.safe_load((REPO / "docker-compose.yml").read_text())
SERVICES: dict[str, dict[str, Any]] = COMPOSE["services"]
OURS = {name: s for name, s in SERVICES.items() if "build" in s}
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())
#: Read by libraries rather than by the app's settings.
THIRD_PARTY_ENV = {"MUJOCO_GL"}
DEBIAN_PACKAGES = ("libegl1", "libegl-mesa0", "libgl1-mesa-dri", "libosmesa6")


def env_names(model: type[BaseSettings]) -> set[str]:
    """The environment variables a pydantic-settings model reads."""
    prefix = model.model_config.get("env_prefix", "")
    names = set()
    for name, field in model.model_fields.items():
        alias = field.validation_alias
        choices = alias.choices if isinstance(alias, AliasChoices) else [alias or prefix + name]
        names |= {c.upper() for c in choices if isinstance(c, str)}
    return names


def argv(command: str | list[str]) -> list[str]:
    return shlex.split(command) if isinstance(command, str) else list(command)


def assert_runs_something_real(args: list[str]) -> None:
    """``args[0]`` is a console script or tool of this project, used as it allows."""
    program, rest = args[0], args[1:]
    if program == "acv":
        assert PYPROJECT["project"]["scripts"]["acv"] == "app.cli:main"
        commands = typer.main.get_command(cli).commands
        assert rest and rest[0] in commands, f"acv has no command {rest[:1]}"
    elif program == "uvicorn":
        target = rest[rest.index("--factory") + 1]
        module, _, attr = target.partition(":")
        assert callable(getattr(importlib.import_module(module), attr)), target
    elif program == "alembic":
        config = ConfigParser(defaults={"here": str(REPO)})
        config.read(REPO / "alembic.ini")
        location = config["alembic"]["script_location"]
        assert (Path(location) / "env.py").is_file() and rest == ["upgrade", "head"]
    elif program == "ray":
        assert (
            any(r.startswith("ray") for r in PYPROJECT["project"]["optional-dependencies"]["ray"])
            and importlib.util.find_spec("ray") is not None
        )
    elif program == "sh":
        assert rest[0] in ("-c", "-ec") and len(rest) == 2, args
        for command in shell_commands(rest[1]):
            assert_runs_something_real(command)
    elif program == "python":
        code = rest[rest.index("-c") + 1]
        for node in ast.walk(ast.parse(code)):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            for name in names:
                assert importlib.util.find_spec(name) is not None, name
    else:
        raise AssertionError(f"unknown program {program!r} in {args}")


def shell_commands(script: str) -> list[list[str]]:
    """The simple commands of a compose ``sh -c`` script (``$$`` is compose's escape of
    ``$``), without ``if``/``then``/``fi``/``exec`` and ``[ ... ]`` tests."""
    commands: list[list[str]] = []
    for line in script.replace("$$", "$").splitlines():
        lexer = shlex.shlex(line, posix=True, punctuation_chars=";&|")
        lexer.whitespace_split = True
        words = [*lexer, ";"]
        while words:
            end = next(i for i, w in enumerate(words) if w in (";", "&&", "||", "|"))
            command, words = words[:end], words[end + 1 :]
            while command and command[0] in ("if", "then", "else", "fi", "exec"):
                command = command[1:]
            if command and command[0] != "[":
                commands.append(command)
    return commands


def published_ports(service: dict[str, Any]) -> list[tuple[str, str]]:
    """``(host address, container port)`` of each port a service publishes; ``0.0.0.0``
    (every interface, Docker's default) where the entry names no address."""
    found = []
    for entry in service.get("ports", []):
        if isinstance(entry, dict):  # the long syntax
            found.append((entry.get("host_ip", "0.0.0.0"), str(entry["target"])))
            continue
        spec = interpolated(str(entry)).split("/")[0]
        match = re.fullmatch(r"(?:(\[[0-9a-f:]+\]|\d+\.\d+\.\d+\.\d+):)?(?:[\d-]*:)?([\d-]+)", spec)
        assert match, f"unparsed port entry {entry!r}"
        found.append((match.group(1) or "0.0.0.0", match.group(2)))
    return found


@pytest.mark.parametrize("name", sorted(OURS))
def test_build_context_and_dockerfile_exist(name: str) -> None:
    build = OURS[name]["build"]
    context = REPO / build["context"]
    assert context.is_dir() and (context / build.get("dockerfile", "Dockerfile")).is_file()


@pytest.mark.parametrize("name", sorted(OURS))
def test_commands_and_health_checks_are_real(name: str) -> None:
    service = OURS[name]
    assert_runs_something_real(argv(service["command"]))
    if "healthcheck" in service:
        test = service["healthcheck"]["test"]
        assert test[0] == "CMD", "health checks of our image run a program, not a shell"
        assert_runs_something_real(test[1:])


@pytest.mark.parametrize("name", sorted(OURS))
def test_environment_is_what_the_settings_read(name: str) -> None:
    known = env_names(Settings) | env_names(JobSettings) | THIRD_PARTY_ENV
    assert set(OURS[name]["environment"]) <= known


def test_the_web_runs_several_workers_of_the_app_factory() -> None:
    args = argv(SERVICES["web"]["command"])
    assert args[:3] == ["uvicorn", "--factory", "app.main:create_app"]
    assert re.fullmatch(r"\$\{WEB_WORKERS:-[2-9]\d*\}|[2-9]\d*", args[args.index("--workers") + 1])
    assert "/healthz" in " ".join(SERVICES["web"]["healthcheck"]["test"])
    assert {r.path for r in importlib.import_module("app.http.health").router.routes} == {
        "/healthz"
    }


def test_migrations_run_once_before_the_web_and_the_worker() -> None:
    assert argv(SERVICES["migrate"]["command"]) == ["alembic", "upgrade", "head"]
    assert SERVICES["migrate"]["restart"] == "no"
    for name in ("web", "worker"):
        assert SERVICES[name]["depends_on"]["migrate"] == {
            "condition": "service_completed_successfully"
        }
    assert SERVICES["migrate"]["depends_on"]["postgres"] == {"condition": "service_healthy"}
    assert "pg_isready" in " ".join(SERVICES["postgres"]["healthcheck"]["test"])


def test_dependencies_volumes_and_profiles_are_declared() -> None:
    declared = set(COMPOSE["volumes"])
    for name, service in SERVICES.items():
        assert set(service.get("depends_on", {})) <= set(SERVICES) - {name}
        for volume in service.get("volumes", []):
            source = volume.split(":")[0]
            assert source.startswith((".", "/")) or source in declared, (name, volume)
    for name in ("web", "worker", "ray-head"):
        assert "acv-data:/data" in SERVICES[name]["volumes"]  # renders and checkpoints
        assert SERVICES[name]["environment"]["ACV_DATA_DIR"] == "/data"
    assert SERVICES["ray-head"]["profiles"] == ["ray"]
    assert SERVICES["worker"]["depends_on"]["ray-head"]["required"] is False


def test_secrets_are_required_from_the_environment() -> None:
    env = SERVICES["web"]["environment"]
    assert env["ACV_ADMIN_TOKEN"].startswith("${ACV_ADMIN_TOKEN:?")
    assert "${POSTGRES_PASSWORD:?" in env["DATABASE_URL"]
    assert SERVICES["postgres"]["environment"]["POSTGRES_PASSWORD"].startswith(
        "${POSTGRES_PASSWORD:?"
    )


def interpolated(text: str) -> str:
    """``text`` with ``${VAR:-default}`` as its default and other variables as ``x``."""
    return re.sub(r"\$\{\w+(?::-([^}]*)|[^}]*)\}", lambda m: m.group(1) or "x", text)


def test_urls_point_at_services_only() -> None:
    """Every URL names a compose service or this host; no outside host appears anywhere."""
    for path in ("docker-compose.yml", "Dockerfile", ".dockerignore"):
        text = interpolated((REPO / path).read_text())
        hosts = re.findall(r"[a-z+]+://(?:[^@/\s]*@)?([^:/\s'\"]+)", text)
        assert set(hosts) <= set(SERVICES) | {"localhost", "127.0.0.1", "0.0.0.0"}, path
    assert interpolated("a${X:?no way}b${Y:-http://web:1}") == "axbhttp://web:1"


def test_dockerfile_installs_the_renderer_and_the_package() -> None:
    text = (REPO / "Dockerfile").read_text()
    install = re.search(r"apt-get install[^\n]*", text).group(0)
    assert all(package in install.split() for package in DEBIAN_PACKAGES)
    assert 'pip install -e ".[ray]"' in text and "COPY . ." in text
    ignored = (REPO / ".dockerignore").read_text().split()
    for needed in (
        "app",
        "engine",
        "migrations",
        "templates",
        "static",
        "alembic.ini",
        "pyproject.toml",
        "README.md",
    ):
        assert (REPO / needed).exists() and needed not in ignored, needed


def test_the_worker_joins_the_ray_cluster_it_submits_to() -> None:
    """``ray.init(address="host:6379")`` connects only from a node of the cluster: with
    ACV_RAY_ADDRESS set, the worker container joins it (``ray start --address``) before it
    becomes ``acv worker`` (``exec``: it gets the stop signal); ``-e``: a failed join stops
    the container instead of running a worker that cannot reach Ray."""
    args = argv(SERVICES["worker"]["command"])
    assert args[:2] == ["sh", "-ec"]
    script = args[2]
    assert "$" not in script.replace("$$", ""), "compose would substitute an unescaped $"
    assert shell_commands(script) == [
        ["ray", "start", "--address=${ACV_RAY_ADDRESS}"],
        ["acv", "worker"],
    ]
    assert re.search(
        r'^if \[ -n "\$\$\{ACV_RAY_ADDRESS\}" \]; then ray start [^\n]*; fi$', script, re.M
    ), "the join happens only with ACV_RAY_ADDRESS set"
    assert script.strip().splitlines()[-1] == "exec acv worker"
    # The address joined is the one the executor connects to: the head's GCS port.
    assert SERVICES["worker"]["environment"]["ACV_RAY_ADDRESS"] == "${ACV_RAY_ADDRESS:-}"
    head = argv(SERVICES["ray-head"]["command"])
    assert head[:3] == ["ray", "start", "--head"] and "--port=6379" in head
    for doc in ("docker-compose.yml", "docs/scale.md"):
        assert (
            "ACV_RAY_ADDRESS=ray-head:6379 docker compose --profile ray up"
            in (REPO / doc).read_text()
        ), doc
    assert shell_commands('if [ -n "$$X" ]; then a b; fi\nexec c && d | e') == [
        ["a", "b"],
        ["c"],
        ["d"],
        ["e"],
    ]


def test_only_the_web_is_published_on_every_interface() -> None:
    """Ray's dashboard (its Jobs API runs any code, unauthenticated), and anything else but
    the web, is published on the host's loopback at most."""
    for name, service in SERVICES.items():
        for address, port in published_ports(service):
            if (name, port) != ("web", "8000"):
                assert address in ("127.0.0.1", "[::1]"), (name, address, port)
    dashboard = [a for a, port in published_ports(SERVICES["ray-head"]) if port == "8265"]
    assert dashboard in ([], ["127.0.0.1"])
    assert published_ports(
        {"ports": ["8265:8265", "8265", {"target": 8265}, "127.0.0.1:8265:8265/tcp", "[::1]:1:2"]}
    ) == [
        ("0.0.0.0", "8265"),
        ("0.0.0.0", "8265"),
        ("0.0.0.0", "8265"),
        ("127.0.0.1", "8265"),
        ("[::1]", "2"),
    ]
