"""``acv study create|list``, ``acv participant add``, ``acv simulate`` and ``acv serve``."""

from __future__ import annotations

import os
import re

import httpx
import pytest

from engine.treefile import load_tree
from tests.support.cli import acv
from tests.support.server import HTTP_TIMEOUT_S, acv_serve, clean_env


@pytest.fixture
def run(monkeypatch, backend_url):
    """Invoke ``acv`` in-process on this module's database."""
    data_dir, url = backend_url
    monkeypatch.setenv("ACV_DATA_DIR", str(data_dir))
    monkeypatch.setenv("DATABASE_URL", url)
    return acv


def test_create_invite_simulate_list(run, tmp_path) -> None:
    created = run(
        "study",
        "create",
        "--name",
        "cli study",
        "--env",
        "Hopper-v5",
        "--candidates",
        "4",
        "--seed",
        "2",
    )
    assert created.exit_code == 0, created.output
    study_id = re.search(r"study (\d+) ready: 4 Hopper-v5 candidates", created.output)[1]
    added = run("participant", "add", "--study", study_id, "--count", "2")
    assert added.exit_code == 0
    assert len(re.findall(r"^http://127\.0\.0\.1:8000/p/\S{43}$", added.output, re.M)) == 2
    simulated = run(
        "simulate",
        "--study",
        study_id,
        "--teacher",
        "standing",
        "--participants",
        "3",
        "--noise",
        "0.1",
    )
    assert simulated.exit_code == 0 and simulated.output.count("finished (standing)") == 3
    finished = re.search(r"participant (\d+) finished", simulated.output)[1]
    tree = tmp_path / "human.json"
    exported = run("participant", "tree", "--participant", finished, "--out", str(tree))
    assert exported.exit_code == 0, exported.output
    assert load_tree(tree).judge == f"participant:{finished}"
    unfinished = run(
        "participant", "tree", "--participant", str(int(finished) - 1), "--out", str(tree)
    )
    assert unfinished.exit_code == 2 and "has not finished the bracket" in unfinished.stderr
    listed = run("study", "list")
    assert re.search(
        rf"^{study_id}\tready\tHopper-v5\t4\t3/5 finished\tcli study$", listed.output, re.M
    )


def test_create_with_practice_pairs_and_ties(run, client, admin) -> None:
    created = run(
        "study",
        "create",
        "--name",
        "practice",
        "--env",
        "Hopper-v5",
        "--candidates",
        "4",
        "--practice-pairs",
        "2",
        "--allow-ties",
    )
    assert created.exit_code == 0, created.output
    study_id = re.search(r"study (\d+) ready", created.output)[1]
    study = client.get(f"/api/studies/{study_id}", headers=admin).json()
    assert (study["practice_pairs"], study["allow_ties"]) == (2, True)
    added = client.post(f"/api/studies/{study_id}/participants", headers=admin).json()
    practice = client.get(
        "/api/participants/me/practice", headers={"Authorization": f"Bearer {added['token']}"}
    )
    assert len(practice.json()) == 2  # its practice states were prepared with it


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["study", "create", "--name", "x", "--env", "CartPole-v1"], "not a MuJoCo env"),
        (["study", "create", "--name", "x", "--candidates", "200"], "n_candidates"),
        (
            ["study", "create", "--name", "x", "--env", "Hopper-v5", "--sampling", "informative"],
            "informative sampling needs a finished no-advice ppo run on Hopper-v5; train one first",
        ),
        (
            ["study", "create", "--name", "x", "--env", "Hopper-v5", "--disagreement-pairs", "2"],
            "disagreement pairs need a finished no-advice ppo run on Hopper-v5; train one first",
        ),
        (["study", "create", "--name", "x", "--disagreement-pairs", "11"], "disagreement_pairs"),
        (
            ["study", "create", "--name", "x", "--practice-pairs", "1"],
            "practice_pairs must be 0 (no practice) or 2 to 5, got 1",
        ),
        (
            ["study", "create", "--name", "x", "--practice-pairs", "6"],
            "practice_pairs must be 0 (no practice) or 2 to 5, got 6",
        ),
        (["participant", "add", "--study", "424242"], "study 424242 not found"),
        (["simulate", "--study", "424242"], "study 424242 not found"),
        (
            ["participant", "tree", "--participant", "424242", "--out", "x.json"],
            "participant 424242 not found",
        ),
        (["simulate", "--study", "1", "--teacher", "oracle"], "unknown teacher"),
        (["simulate", "--study", "1", "--noise", "2"], "noise"),
        # a path through a file: any OSError names the path
        (
            ["study", "create", "--name", "x", "--instructions-file", "/etc/hostname/x"],
            "Not a directory: '/etc/hostname/x'",
        ),
    ],
)
def test_bad_input_is_one_line_and_exit_2(run, args: list[str], message: str) -> None:
    result = run(*args)
    assert result.exit_code == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "args",
    [
        ["participant", "add", "--study"],
        ["participant", "tree", "--out", "x.json", "--participant"],
        ["export", "--study"],
        ["survey", "results", "--survey"],
    ],
)
def test_an_id_past_the_id_columns_is_a_usage_error(run, args: list[str]) -> None:
    """Ids are 32-bit: a larger one was SQLite's OverflowError (a traceback) or PostgreSQL's
    out-of-range error; now the option's own bound, the same on both."""
    result = run(*args, "9" * 20)
    assert result.exit_code == 2 and "2147483647" in result.stderr, result.stderr


@pytest.mark.process
def test_serve_migrates_a_fresh_database_and_prints_the_login_url(tmp_path) -> None:
    log = tmp_path / "server.log"
    with acv_serve(clean_env(ACV_DATA_DIR=str(tmp_path / "fresh")), log, "--no-access-log") as base:
        token = (tmp_path / "fresh" / "admin_token").read_text().strip()
        studies = httpx.get(
            f"{base}/api/studies",
            headers={"Authorization": f"Bearer {token}"},
            timeout=HTTP_TIMEOUT_S,
        )
        assert studies.json() == []  # the schema exists: migrations ran
    assert f"researcher login: {base}/login#token={token}" in log.read_text()


def test_serve_never_prints_a_configured_admin_token(monkeypatch, tmp_path) -> None:
    """ACV_ADMIN_TOKEN ends up in journald or docker logs if printed: only the /login URL
    is shown (a generated token is printed in the #token= link, see above)."""
    import uvicorn

    token = "configured-admin-token-0123456789abcdef"
    monkeypatch.setattr(uvicorn, "run", lambda *_, **__: None)  # print the banner, serve nothing
    for name in [k for k in os.environ if k.startswith("ACV_") or k == "DATABASE_URL"]:
        monkeypatch.delenv(name)
    monkeypatch.setenv("ACV_DATA_DIR", str(tmp_path))
    monkeypatch.setenv("ACV_ADMIN_TOKEN", token)
    result = acv("serve", "--port", "8123")
    assert result.exit_code == 0, result.output
    assert token not in result.output and "#token=" not in result.output
    assert (
        "researcher login: http://127.0.0.1:8123/login  (with the admin token set in "
        "ACV_ADMIN_TOKEN)" in result.output
    )
