"""``acv train``, ``acv agent-tree`` and ``acv plot`` as a user runs them (in-process)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from PIL import Image

from app.cli import main
from engine.pipeline import replay_with_teacher, run_tournament
from engine.pooling import pooled_tree
from engine.treefile import dump_tree, load_tree, tree_to_json

pytestmark = pytest.mark.training

TINY = ["--timesteps", "256", "--n-envs", "2", "--num-steps", "64", "--checkpoint-every", "128"]


def acv(monkeypatch, capsys, *args: str) -> tuple[int, str]:
    """Run ``acv ARGS``; return the exit code and stderr."""
    monkeypatch.setattr(sys, "argv", ["acv", *args])
    with pytest.raises(SystemExit) as exc:
        main()
    return exc.value.code or 0, capsys.readouterr().err


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cli") / "human.json"
    dump_tree(
        run_tournament(env_id="Hopper-v5", n_candidates=6, p=0.9, seed=2, teacher="standing"), path
    )
    return path


def test_train_then_agent_tree_then_compare_then_plot(
    monkeypatch, capsys, tree: Path, tmp_path: Path
) -> None:
    run = tmp_path / "case2"
    code, err = acv(
        monkeypatch,
        capsys,
        "train",
        "--advice",
        str(tree),
        "--algo",
        "bipars-mgl",
        "--seed",
        "0",
        "--out",
        str(run),
        *TINY,
    )
    assert code == 0, err
    assert json.loads((run / "config.json").read_text())["env_id"] == "Hopper-v5"
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["step_128.pt", "step_256.pt"]
    agent = tmp_path / "agent.json"
    code, err = acv(
        monkeypatch,
        capsys,
        "agent-tree",
        "--run",
        str(run),
        "--checkpoint",
        "128",
        "--judge",
        "shaped-value",
        "--out",
        str(agent),
    )
    assert code == 0, err
    code, err = acv(monkeypatch, capsys, "compare", str(tree), str(agent), "--json")
    assert code == 0, err
    png = tmp_path / "curves.png"
    code, err = acv(monkeypatch, capsys, "plot", "--runs", str(run), "--out", str(png))
    assert code == 0, err
    assert Image.open(png).size[0] > 300


def test_reward_advice_and_the_behaviour_judge_from_the_cli(
    monkeypatch, capsys, tree: Path, tmp_path: Path
) -> None:
    run = tmp_path / "case1"
    code, err = acv(
        monkeypatch,
        capsys,
        "train",
        "--advice",
        str(tree),
        "--algo",
        "bipars-em",
        "--advice-mode",
        "reward",
        "--out",
        str(run),
        *TINY,
    )
    assert code == 0, err
    assert json.loads((run / "config.json").read_text())["advice_mode"] == "reward"
    agent = tmp_path / "agent.json"
    code, err = acv(
        monkeypatch,
        capsys,
        "agent-tree",
        "--run",
        str(run),
        "--judge",
        "behaviour",
        "--episodes",
        "2",
        "--max-steps",
        "200",
        "--out",
        str(agent),
    )
    assert code == 0, err
    assert json.loads(agent.read_text())["judge"] == "agent:behaviour@256"
    monkeypatch.setattr(sys, "argv", ["acv", "compare", str(tree), str(agent), "--json"])
    with pytest.raises(SystemExit):
        main()
    printed = json.loads(capsys.readouterr().out)
    assert {"contested", "reference_agreement"} <= set(printed)
    for options, message in (
        (["--judge", "behaviour", "--episodes", "0"], "episodes >= 1"),
        (["--burn-in", "-1"], "burn_in >= 0"),
        (["--return-rollouts", "4"], "rollouts >= 5"),
        (["--judge", "vibes"], "unknown judge"),
    ):
        code, err = acv(
            monkeypatch, capsys, "agent-tree", "--run", str(run), *options, "--out", str(agent)
        )
        assert code == 2 and message in err, err
    tiny_return = ["--return-rollouts", "5", "--horizon", "20"]
    code, err = acv(
        monkeypatch, capsys, "agent-tree", "--run", str(run), *tiny_return, "--out", str(agent)
    )
    assert code == 0, err
    assert json.loads(agent.read_text())["judge"] == "agent:return@256"  # the default judge


def test_pool_weights_from_the_cli(monkeypatch, capsys, tree: Path, tmp_path: Path) -> None:
    """``--pool-weight`` once per ``--advice`` tree: F and the pooled verdict are weighted."""
    other = tmp_path / "other.json"
    dump_tree(replay_with_teacher(load_tree(tree), "good"), other)
    run = tmp_path / "weighted"
    pool = ["--advice", str(tree), "--advice", str(other), "--algo", "bipars-em"]
    weights = ["--pool-weight", "0.9", "--pool-weight", "0.1"]
    code, err = acv(monkeypatch, capsys, "train", *pool, *weights, "--out", str(run), *TINY)
    assert code == 0, err
    assert json.loads((run / "config.json").read_text())["pool_weights"] == [0.9, 0.1]
    verdict = pooled_tree([load_tree(tree), load_tree(other)], weights=[0.9, 0.1])
    assert tree_to_json(load_tree(run / "advice.json")) == tree_to_json(verdict)
    code, err = acv(monkeypatch, capsys, "train", "--resume", *weights[:2], "--out", str(run))
    assert code == 2 and "pool_weights=(0.9,)" in err


def test_resume_continues_a_run_and_refuses_other_options(
    monkeypatch, capsys, tree: Path, tmp_path: Path
) -> None:
    run = tmp_path / "r"
    assert (
        acv(
            monkeypatch,
            capsys,
            "train",
            "--algo",
            "ppo",
            "--env",
            "Hopper-v5",
            "--out",
            str(run),
            *TINY,
        )[0]
        == 0
    )
    assert acv(monkeypatch, capsys, "train", "--resume", "--out", str(run))[0] == 0
    code, err = acv(monkeypatch, capsys, "train", "--resume", "--seed", "9", "--out", str(run))
    assert code == 2 and "seed=9" in err


@pytest.mark.parametrize(
    "args, message",
    [
        (["train", "--algo", "sarsa"], "unknown algo"),
        (["train", "--algo", "ppo", "--timesteps", "-10"], "timesteps must be positive"),
        (["train", "--algo", "bipars-em"], "needs advice"),
        (
            ["train", "--algo", "bipars-em", "--advice", "{tree}", "--env", "Humanoid-v5"],
            "tree is for Hopper-v5",
        ),
        (
            ["agent-tree", "--run", "{tmp}", "--out", "{tmp}/a.json"],
            "no config.json|no advice|trained without advice",
        ),
        (["plot", "--runs", "{tmp}/missing"], "not a training run"),
        (["train", "--algo", "ppo", "--seed", "-1"], "seed must be in 0"),
        (["train", "--algo", "ppo", "--env", "NoSuchEnv-v0"], "unknown env 'NoSuchEnv-v0'"),
        (
            ["train", "--algo", "ppo", "--n-envs", "1", "--num-steps", "32"],
            "raise --n-envs or --num-steps",
        ),
        (
            ["train", "--algo", "ppo-shaped", "--advice", "{tree}", "--advice-mode", "best"],
            "unknown advice mode 'best'",
        ),
        (
            ["train", "--algo", "ppo-shaped", "--advice", "{tree}"]
            + ["--pool-weight", "1", "--pool-weight", "2"],
            "pool weights need pooled advice",
        ),
        (
            ["train", "--algo", "ppo", "--pool-weight", "-1", "--pool-weight", "1"],
            "pool weights must be",
        ),
    ],
)
def test_bad_input_exits_2_with_one_line(
    monkeypatch, capsys, tree: Path, tmp_path: Path, args: list[str], message: str
) -> None:
    args = [a.format(tree=tree, tmp=tmp_path) for a in args]
    if args[0] == "train":
        args += ["--out", str(tmp_path / "run")]
    code, err = acv(monkeypatch, capsys, *args)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("acv: error:")
    assert any(m in err for m in message.split("|")), err
    assert not (tmp_path / "run").exists()  # nothing left that would refuse a retry


def test_corrupt_and_foreign_checkpoints_exit_2(
    monkeypatch, capsys, tree: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    assert (
        acv(
            monkeypatch,
            capsys,
            "train",
            "--algo",
            "ppo-shaped",
            "--advice",
            str(tree),
            "--out",
            str(run),
            *TINY,
        )[0]
        == 0
    )
    (run / "checkpoints" / "step_999.pt").write_bytes(b"\x00garbage")
    code, err = acv(
        monkeypatch, capsys, "agent-tree", "--run", str(run), "--out", str(tmp_path / "a.json")
    )
    assert code == 2 and "not a readable checkpoint" in err
