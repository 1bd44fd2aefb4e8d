"""Start-up: a bad data dir, database or token file stops ``acv serve`` with one clear line
and exit code 2 before it serves anything; and the start-up work of several processes at
once (migrations, the admin token, resuming half-prepared studies) does not race.

The read-only and full data dirs are real: a read-only bind mount and a 1 MiB tmpfs, each
in a private mount namespace (``unshare -m``) so that nothing leaks to the host (root
ignores file modes, so ``chmod`` could not make a directory read-only for these tests).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
import uvicorn
from sqlalchemy import func, select

from app.db import make_engine, make_sessions, upgrade
from app.models import Candidate, Study
from app.runtime import Runtime
from app.settings import Settings
from app.studies.service import StudySpec, create_study
from tests.support.cli import acv
from tests.support.net import free_port, listening
from tests.support.postgres import BACKENDS, empty_database
from tests.support.server import clean_env
from tests.support.web import ADMIN_TOKEN

REPO = Path(__file__).resolve().parents[3]
SERVE = [
    sys.executable,
    "-c",
    "from app.cli import main; main()",
    "serve",
    "--host",
    "127.0.0.1",
    "--no-access-log",
]


def serve(env: dict[str, str], *, setup: str | None = None) -> subprocess.CompletedProcess:
    """Run ``acv serve`` (after shell ``setup`` in a private mount namespace, if given) and
    wait for it to exit; a server that starts serving instead fails the test."""
    port = free_port()
    command = [*SERVE, "--port", str(port)]
    if setup is not None:
        assert shutil.which("unshare"), "these tests need util-linux's unshare"
        command = ["unshare", "-m", "--", "sh", "-ec", f"{setup}\nexec {shlex.join(command)}"]
    try:
        done = subprocess.run(
            command, cwd=REPO, env=clean_env(**env), capture_output=True, text=True, timeout=60
        )
    except subprocess.TimeoutExpired:
        pytest.fail("acv serve started instead of refusing the data dir")
    assert not listening(port), "something listens on the port"
    return done


def assert_refused(code: int, stderr: str, stdout: str, *needles: str) -> None:
    """Exit code 2, one ``acv: error:`` line naming the problem, no traceback, not served."""
    lines = stderr.strip().splitlines()
    assert code == 2, stderr[-2000:]
    assert len(lines) == 1 and lines[0].startswith("acv: error: "), stderr[-2000:]
    assert all(n in lines[0] for n in needles), lines[0]
    assert "Uvicorn running" not in stdout + stderr


def refused(done: subprocess.CompletedProcess, *needles: str) -> None:
    assert_refused(done.returncode, done.stderr, done.stdout, *needles)


@pytest.fixture
def serve_here(monkeypatch) -> Callable[..., None]:
    """``acv serve`` in this process with ``env``, asserting it is refused (uvicorn would
    fail the test); cheaper than a subprocess where no mount namespace is needed."""

    def served(*_: object, **__: object) -> None:
        pytest.fail("acv serve started serving")

    monkeypatch.setattr(uvicorn, "run", served)

    def check(env: dict[str, str], *needles: str) -> None:
        for name in [k for k in os.environ if k.startswith("ACV_") or k == "DATABASE_URL"]:
            monkeypatch.delenv(name)
        for name, value in env.items():
            monkeypatch.setenv(name, value)
        result = acv("serve", "--port", free_port())
        assert_refused(result.exit_code, result.stderr, result.stdout, *needles)

    return check


def test_data_dir_under_a_file(serve_here, tmp_path: Path) -> None:
    (tmp_path / "file").write_text("not a directory")
    serve_here({"ACV_DATA_DIR": str(tmp_path / "file" / "data")}, "data dir", "Not a directory")


@pytest.mark.process
@pytest.mark.parametrize("backend", BACKENDS)
def test_read_only_data_dir(request, tmp_path: Path, backend: str) -> None:
    """Also with PostgreSQL, where nothing else would notice before the first study's images
    (a half-started server)."""
    data = tmp_path / "data"
    env = {"ACV_DATA_DIR": str(data)}
    if backend == "postgresql":
        env |= {
            "DATABASE_URL": request.getfixturevalue("postgres").create_database(),
            "ACV_ADMIN_TOKEN": ADMIN_TOKEN,
        }
    data.mkdir()
    setup = f"mount --bind {data} {data}; mount -o remount,bind,ro {data}"
    refused(serve(env, setup=setup), str(data), "Read-only file system")


@pytest.mark.process
@pytest.mark.parametrize(
    ("min_free_mb", "needle"), [("64", "MiB free"), ("0", "No space left on device")]
)
def test_full_data_dir(tmp_path: Path, min_free_mb: str, needle: str) -> None:
    """A 1 MiB tmpfs filled up: refused by the free-space check, and (with the check off)
    by the write probe."""
    data = tmp_path / "data"
    data.mkdir()
    setup = (
        f"mount -t tmpfs -o size=1m tmpfs {data}\n"
        f"head -c 2000000 /dev/zero > {data}/fill 2>/dev/null || true"
    )
    done = serve({"ACV_DATA_DIR": str(data), "ACV_MIN_FREE_MB": min_free_mb}, setup=setup)
    refused(done, str(data), needle)


def test_corrupt_sqlite_database(serve_here, tmp_path: Path) -> None:
    (tmp_path / "acv.sqlite3").write_bytes(b"this is not a database" * 100)
    serve_here({"ACV_DATA_DIR": str(tmp_path)}, "database")


def test_unreachable_postgresql(serve_here, tmp_path: Path) -> None:
    url = f"postgresql://acv@127.0.0.1:{free_port()}/acv"
    serve_here({"ACV_DATA_DIR": str(tmp_path), "DATABASE_URL": url}, "database")


@pytest.mark.parametrize(
    ("env", "needle"),
    [
        ({"ACV_ADMIN_TOKEN": "  "}, "admin token"),
        ({"ACV_THREADS": "many"}, "threads"),
        ({"ACV_ADMIN_TOKEN": "a"}, "ACV_ADMIN_TOKEN has 1 characters; use at least 32"),
        ({"ACV_ADMIN_TOKEN": "x" * 31}, "at least 32"),
        ({"ACV_SESSION_HOURS": "0"}, "session_hours"),
        ({"DATABASE_URL": "nosuchdb://x"}, "DATABASE_URL"),
    ],
)
def test_bad_settings(serve_here, tmp_path: Path, env: dict[str, str], needle: str) -> None:
    serve_here({"ACV_DATA_DIR": str(tmp_path)} | env, needle)


def test_empty_admin_token_file(serve_here, tmp_path: Path) -> None:
    (tmp_path / "admin_token").write_text("\n")
    serve_here({"ACV_DATA_DIR": str(tmp_path)}, "admin token", "empty")


def _at_once(code: str, *args: str, n: int = 4) -> list[subprocess.CompletedProcess]:
    """Run ``code`` in ``n`` fresh interpreters that start its real work at the same moment
    (``START`` is a wall-clock time a few seconds ahead, after their imports)."""
    start = str(time.time() + 4.0)
    prelude = "import sys, time\nSTART = float(sys.argv[1])\n"
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", prelude + code, start, *args],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(n)
    ]
    results = []
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        results.append(subprocess.CompletedProcess(proc.args, proc.returncode, out, err))
    return results


@pytest.mark.process
@pytest.mark.parametrize("backend", BACKENDS)
def test_concurrent_migrations_of_a_fresh_database(request, tmp_path: Path, backend: str) -> None:
    url = empty_database(request, tmp_path, backend)
    code = (
        "from app.db import upgrade\n"
        "time.sleep(max(0.0, START - time.time()))\nupgrade(sys.argv[2])\n"
    )
    for done in _at_once(code, url):
        assert done.returncode == 0, done.stderr[-2000:]
    upgrade(url)  # already at head: nothing to do


@pytest.mark.process
def test_concurrent_processes_agree_on_one_admin_token(tmp_path: Path) -> None:
    code = (
        "from app.core.auth import ensure_admin_token\n"
        "from app.settings import Settings\n"
        "settings = Settings(data_dir=sys.argv[2])\n"
        "time.sleep(max(0.0, START - time.time()))\n"
        "print(ensure_admin_token(settings))\n"
    )
    results = _at_once(code, str(tmp_path), n=6)
    tokens = {done.stdout.strip() for done in results}
    assert all(done.returncode == 0 for done in results), [d.stderr for d in results]
    assert len(tokens) == 1 and len(tokens.pop()) >= 43
    assert sorted(p.name for p in tmp_path.iterdir()) == ["admin_token"]  # no leftovers


@pytest.mark.postgres
def test_two_workers_resume_the_same_half_prepared_study(postgres, tmp_path: Path) -> None:
    """Every web worker resumes half-prepared studies at start-up; the study ends ``ready``
    with its candidates stored once, not ``failed`` by the slower worker."""
    url = postgres.create_database()
    upgrade(url)
    settings = Settings(data_dir=tmp_path, database_url=url, admin_token=ADMIN_TOKEN)
    engine = make_engine(url)
    with make_sessions(engine)() as session:
        study = create_study(session, spec=StudySpec("resumed", "Hopper-v5", 4, 0.9, seed=1))
    workers = [Runtime(settings), Runtime(settings)]
    try:
        for runtime in workers:
            runtime.resume()
    finally:
        for runtime in workers:
            runtime.close()  # waits for the queued preparations
    with make_sessions(engine)() as session:
        stored = session.get(Study, study.id)
        count = session.scalar(select(func.count()).where(Candidate.study_id == study.id))
    engine.dispose()
    assert (stored.status, stored.error, count) == ("ready", None, 4)
