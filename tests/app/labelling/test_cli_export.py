"""``acv export --format hf`` (issue 29 §4), on SQLite and PostgreSQL: the folder it writes
loads with ``datasets`` and holds only participants who agreed to share; ``--push-to-hub``
publishes it through ``huggingface_hub`` to a local stand-in for the Hub (``HF_ENDPOINT`` on
127.0.0.1: no test reaches the network). Bad input is one line on stderr and exit code 2,
and writes nothing."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from sqlalchemy import create_engine, select, update
from sqlalchemy.orm import Session

from app.models import Member, Participant
from tests.support.cli import acv
from tests.support.hf import card, check_tables, load
from tests.support.hub import local_hub


@pytest.fixture
def run(monkeypatch, backend_url):
    """Invoke ``acv`` in-process on this module's database, with no Hub token."""
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    monkeypatch.delenv("HF_TOKEN", raising=False)
    return acv


def played_study(run, backend_url, *, shared: int) -> str:
    """A 4-candidate study whose two simulated participants played the bracket, the first
    ``shared`` of them agreeing to share (a participant's own choice: set in the database)."""
    made = run("study", "create", "--name", "x", "--env", "Hopper-v5", "--candidates", "4")
    assert made.exit_code == 0, made.output
    study = re.search(r"study (\d+) ready", made.output)[1]
    played = run("simulate", "--study", study, "--teacher", "good", "--participants", 2)
    assert played.exit_code == 0, played.output
    engine = create_engine(backend_url[1])
    with Session(engine) as session, session.begin():
        mine = Participant.study_id == int(study)
        ids = session.scalars(select(Participant.id).where(mine).order_by(Participant.id)).all()
        agreed = Member.id.in_(ids[:shared])
        session.execute(update(Member).where(agreed).values(share_consent=True))
    engine.dispose()
    return study


def test_export_writes_a_folder_datasets_loads(run, backend_url, tmp_path: Path) -> None:
    study = played_study(run, backend_url, shared=1)
    out = tmp_path / "ds"
    done = run("export", "--study", study, "--format", "hf", "--out", out, "--license", "mit")
    assert done.exit_code == 0, done.output
    assert "1 participants, 3 labels, 1 trees, 4 candidates" in done.output
    tables = load(out, tmp_path / "cache")
    check_tables(tables, n_candidates=4)
    assert tables["participants"].num_rows == 1 and tables["labels"].num_rows == 3
    assert card(out)["license"] == "mit"
    again = tmp_path / "again"
    assert run("export", "--study", study, "--out", again).exit_code == 0
    assert (
        load(again, tmp_path / "cache2")["labels"]["participant"] == tables["labels"]["participant"]
    )


def test_push_to_hub_goes_to_the_local_stand_in(
    run, backend_url, monkeypatch, tmp_path: Path
) -> None:
    study = played_study(run, backend_url, shared=2)
    with local_hub() as hub:
        monkeypatch.setenv("HF_ENDPOINT", hub.url)
        monkeypatch.setenv("HF_TOKEN", "hf_test_token")
        monkeypatch.setenv("HF_HUB_DISABLE_TELEMETRY", "1")
        out = tmp_path / "ds"
        done = run(
            "export", "--study", study, "--out", out, "--push-to-hub", "lab/acv", "--private"
        )
    assert done.exit_code == 0, done.output
    assert f"pushed to {hub.url}/datasets/lab/acv/commit/" in done.output
    assert (
        hub.repos["lab/acv"]["type"] == "dataset"
        and hub.repos["lab/acv"]["visibility"] == "private"
    )
    written = {p.relative_to(out).as_posix(): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert hub.files["lab/acv"] == written  # every file, byte for byte
    assert hub.metadata[0]["configs"][0]["config_name"] == "labels"
    assert {auth for *_, auth in hub.requests} == {"Bearer hf_test_token"}


def test_a_hub_that_refuses_is_one_line(run, backend_url, monkeypatch, tmp_path: Path) -> None:
    study = played_study(run, backend_url, shared=1)
    with local_hub() as hub:
        monkeypatch.setenv("HF_ENDPOINT", hub.url + "/nowhere")
        monkeypatch.setenv("HF_TOKEN", "hf_test_token")
        done = run("export", "--study", study, "--out", tmp_path / "ds", "--push-to-hub", "a/b")
    assert done.exit_code == 2
    assert done.stderr.startswith("acv: error: could not push to the Hub dataset a/b")
    assert done.stderr.count("\n") == 1


@pytest.mark.parametrize(
    ("args", "env", "says"),
    [
        ((), {}, "no participant who agreed to share"),
        (("--push-to-hub", "lab/acv"), {}, "needs a Hub token with write access in HF_TOKEN"),
        (("--push-to-hub", "not a repo"), {"HF_TOKEN": "t"}, "--push-to-hub 'not a repo'"),
        (("--license", "Not A Licence"), {}, "is not a licence id"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(
    run, backend_url, monkeypatch, tmp_path: Path, args, env, says: str
) -> None:
    study = played_study(run, backend_url, shared=0 if not args else 1)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    out = tmp_path / "ds"
    done = run("export", "--study", study, "--out", out, *args)
    assert done.exit_code == 2, done.output
    assert says in done.stderr and done.stderr.count("\n") == 1
    assert not out.exists()


def test_an_unknown_study_or_a_used_folder_exits_2(run, backend_url, tmp_path: Path) -> None:
    assert run("export", "--study", 999_999, "--out", tmp_path / "x").exit_code == 2
    study = played_study(run, backend_url, shared=1)
    used = tmp_path / "used"
    used.mkdir()
    (used / "notes.txt").write_text("keep me")
    done = run("export", "--study", study, "--out", used)
    assert done.exit_code == 2 and "is not an empty folder" in done.stderr
    assert [p.name for p in used.iterdir()] == ["notes.txt"]
