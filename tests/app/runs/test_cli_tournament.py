"""``acv tournament`` and ``acv compare``. The bracket files come from fresh processes, as a
user makes them (the same seed gives the same bytes across interpreters); the rest runs in this
process, since each fresh interpreter costs seconds of imports and the one-line message and
exit code 2 are the command tree's own (``app.cli.root``), in or out of process."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.cli import acv, acv_process

pytestmark = pytest.mark.process


@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("trees")
    for name in ("a", "b"):
        r = acv_process(
            "tournament",
            "--env",
            "Hopper-v5",
            "--candidates",
            "6",
            "--seed",
            "4",
            "--teacher",
            "standing",
            "--out",
            f"{name}.json",
            cwd=d,
        )
        assert r.returncode == 0, r.stderr
    r = acv("tournament", "--replay", d / "a.json", "--teacher", "good", "--out", d / "good.json")
    assert r.exit_code == 0, r.output
    return d


def test_same_seed_gives_identical_bytes(trees: Path) -> None:
    assert (trees / "a.json").read_bytes() == (trees / "b.json").read_bytes()


def test_compare_json(trees: Path) -> None:
    r = acv("compare", trees / "a.json", trees / "good.json", "--json")
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert {
        "match_agreement",
        "match_agreement_ci",
        "kendall_tau_b",
        "tree_edit_distance",
        "same_champion",
        "rejected",
    } <= set(out)
    assert out["n_matches"] == 5
    assert len(out["rejected"]) == out["n_matches"] - out["n_agree"]


def test_compare_table_against_itself(trees: Path) -> None:
    r = acv("compare", trees / "a.json", trees / "a.json")
    assert r.exit_code == 0 and "5/5 = 1.000" in r.stdout


def _write_variants(d: Path) -> None:
    """Files for the bad-input cases: a foreign bracket, a one-candidate tree, a broken one."""
    (d / "garbage.txt").write_text("{not json")
    if not (d / "other.json").exists():
        r = acv(
            "tournament",
            "--env",
            "Hopper-v5",
            "--candidates",
            "6",
            "--seed",
            "9",
            "--teacher",
            "good",
            "--out",
            d / "other.json",
        )
        assert r.exit_code == 0, r.output
    doc = json.loads((d / "a.json").read_text())
    lone = {
        **doc,
        "candidates": doc["candidates"][:1],
        "first_round": [[0, None]],
        "matches": [],
        "tree": {
            "root": 0,
            "nodes": [
                {
                    "state": 0,
                    "parent": None,
                    "height": 0,
                    "depth": 1,
                    "weight": None,
                    "reward": -doc["tree_reward"]["r_b"],
                }
            ],
        },
    }
    (d / "lone.json").write_text(json.dumps(lone))
    (d / "notree.json").write_text(json.dumps({k: v for k, v in doc.items() if k != "tree"}))
    (d / "negseed.json").write_text(json.dumps({**doc, "seed": -1}))


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["tournament", "--candidates", "1", "--out", "x.json"], "at least 2"),
        (["tournament", "--p", "1.5", "--out", "x.json"], "--p must be in [0, 1]"),
        (["tournament", "--seed", "-1", "--out", "x.json"], "seed must be in 0"),
        (["tournament", "--env", "NoSuchEnv-v0", "--out", "x.json"], "unknown env"),
        (["tournament", "--teacher", "oracle", "--out", "x.json"], "unknown teacher"),
        (
            ["tournament", "--sampling", "informative", "--out", "x.json"],
            "--sampling informative needs --baseline, a finished no-advice ppo run",
        ),
        (
            ["tournament", "--baseline", "missing", "--out", "x.json"],
            "--baseline is for --sampling informative only",
        ),
        (
            ["tournament", "--replay", "missing.json", "--teacher", "good", "--out", "x.json"],
            "cannot read tree file",
        ),
        (
            ["tournament", "--replay", "negseed.json", "--teacher", "good", "--out", "x.json"],
            "seed must be in 0",
        ),
        (["compare", "a.json", "garbage.txt"], "invalid JSON"),
        (["compare", "a.json", "other.json"], "different brackets"),
        (["compare", "lone.json", "lone.json"], "at least 2 candidates"),
        (["compare", "a.json", "notree.json"], "missing key 'tree'"),
        (["render", "--tree", "notree.json", "--out", "renders"], "missing key 'tree'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    trees: Path, monkeypatch: pytest.MonkeyPatch, args: list[str], words: str
) -> None:
    _write_variants(trees)
    monkeypatch.chdir(trees)
    r = acv(*args)
    assert r.exit_code == 2, r.output
    assert r.stderr.startswith("acv: error:") and len(r.stderr.strip().splitlines()) == 1
    assert words in r.stderr, r.stderr
    assert not (trees / "x.json").exists()


def test_invalid_mujoco_gl_is_one_line_and_exit_2(trees: Path) -> None:
    r = acv_process("compare", "a.json", "a.json", cwd=trees, env={"MUJOCO_GL": "foo"})
    assert r.returncode == 2
    assert r.stderr.startswith("acv: error: invalid MUJOCO_GL='foo'")
    assert len(r.stderr.strip().splitlines()) == 1 and "egl" in r.stderr


def _set_number(doc: dict, where: str, token: str) -> str:
    """The document as JSON text with the number at ``where`` written as ``token`` (``NaN``,
    ``Infinity``, ``1e999``: Python's JSON reader takes all three)."""
    doc = json.loads(json.dumps(doc))
    if where == "env_reward":
        doc["candidates"][1]["env_reward"] = "@NUMBER@"
    elif where == "score":
        for c in doc["candidates"]:
            c.setdefault("score", 1.0)
        doc["candidates"][0]["score"] = "@NUMBER@"
    else:
        doc["tree_reward"][where] = "@NUMBER@"
    return json.dumps(doc).replace('"@NUMBER@"', token)


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
@pytest.mark.parametrize("where", ["env_reward", "score", "r_b", "r_e"])
def test_non_finite_numbers_in_a_tree_file_exit_2(trees: Path, where: str, token: str) -> None:
    doc = json.loads((trees / "a.json").read_text())
    (trees / "bad.json").write_text(_set_number(doc, where, token))
    r = acv("compare", trees / "a.json", trees / "bad.json")
    assert r.exit_code == 2, r.output
    assert r.stderr.startswith("acv: error:") and len(r.stderr.strip().splitlines()) == 1
    assert "must be a finite number" in r.stderr, r.stderr


@pytest.mark.slow
@pytest.mark.training
def test_informative_tournament_follows_a_baseline_run(tmp_path: Path) -> None:
    """``--sampling informative --baseline RUN`` samples from a no-advice run's policy; the
    same seed gives the same tree, and a run on another env is refused."""
    from engine.rl.config import TrainConfig
    from engine.rl.runner import train

    run = tmp_path / "ppo"
    tiny = {"n_envs": 1, "num_steps": 128, "num_minibatches": 4, "update_epochs": 1}
    train(TrainConfig(algo="ppo", env_id="Hopper-v5", total_timesteps=128, **tiny), None, run)
    args = ["tournament", "--env", "Hopper-v5", "--candidates", "4", "--p", "0", "--seed", "2"]
    for name in ("a", "b"):
        r = acv_process(
            *args,
            "--sampling",
            "informative",
            "--baseline",
            str(run),
            "--out",
            f"{name}.json",
            cwd=tmp_path,
        )
        assert r.returncode == 0, r.stderr
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    assert len(json.loads((tmp_path / "a.json").read_text())["candidates"]) == 4
    other = [*args[:2], "Walker2d-v5", *args[3:]]
    r = acv_process(
        *other, "--sampling", "informative", "--baseline", str(run), "--out", "x.json", cwd=tmp_path
    )
    assert r.returncode == 2 and "--baseline must be a no-advice ppo run on Walker2d-v5" in r.stderr
