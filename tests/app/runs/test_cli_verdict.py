"""``acv verdict`` on tiny trained runs, in-process: the sentence, the JSON, bad input, and
what TensorBoard shows of the runs (each run's hyper-parameters, the verdict's numbers)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from engine.pipeline import run_tournament
from engine.rl.checkpoint import list_checkpoints
from engine.treefile import dump_tree
from tests.support.tensorboard import events, hparams, last_scalars

pytestmark = pytest.mark.training

TINY = ["--timesteps", "128", "--n-envs", "2", "--num-steps", "64", "--checkpoint-every", "128"]


def acv(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    """Run ``acv ARGS``; return the exit code, stdout and stderr."""
    monkeypatch.setattr(sys, "argv", ["acv", *args])
    with pytest.raises(SystemExit) as exc:
        main()
    out = capsys.readouterr()
    return exc.value.code or 0, out.out, out.err


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """An advice tree, two advised seeds, two baseline seeds and one pilot seed (7)."""
    root = tmp_path_factory.mktemp("verdict")
    doc = run_tournament(env_id="Hopper-v5", n_candidates=6, p=0.9, seed=2, teacher="standing")
    dump_tree(doc, root / "human.json")
    mp = pytest.MonkeyPatch()
    for name, algo, seed in [
        ("adv0", "ppo-shaped", 0),
        ("adv1", "ppo-shaped", 1),
        ("base0", "ppo", 0),
        ("base1", "ppo", 1),
        ("pilot7", "ppo", 7),
    ]:
        advice = ["--advice", str(root / "human.json")] if algo != "ppo" else []
        mp.setattr(sys, "argv", ["acv", "train", *advice, "--algo", algo, "--seed", str(seed)])
        sys.argv += ["--env", "Hopper-v5", "--out", str(root / name), *TINY]
        with pytest.raises(SystemExit) as exc:
            main()
        assert not exc.value.code
    mp.undo()
    return root


def _args(root: Path, *, pilot: str = "pilot7", baseline: str = "base0") -> list[str]:
    return [
        "verdict",
        "--advice",
        str(root / "human.json"),
        "--advised",
        str(root / "adv0"),
        "--advised",
        str(root / "adv1"),
        "--baseline",
        str(root / baseline),
        "--baseline",
        str(root / "base1"),
        "--pilot",
        str(root / pilot),
        "--judge",
        "shaped",
    ]


def test_verdict_prints_the_sentence_and_the_json(monkeypatch, capsys, runs: Path) -> None:
    code, out, err = acv(monkeypatch, capsys, *_args(runs))
    assert code == 0, err
    assert out.startswith("On ") and "cannot tell" in out  # 2 seeds against 2 never reach 0.05
    code, out, err = acv(monkeypatch, capsys, *_args(runs), "--json")
    assert code == 0, err
    obj = json.loads(out)
    assert obj["outcome"] == "cannot-tell" and obj["min_detectable_delta"] is None
    n = sum(len(obj["matches"][k]) for k in ("contested", "agreed", "uninformative"))
    assert n == 5  # every match of the 6-player bracket, each in one class


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"pilot": "base1"}, "listed twice"),
        ({"baseline": "adv0"}, "train without advice"),
        ({"pilot": "base0", "baseline": "pilot7"}, "pilot seed(s) 0 are also evaluation seeds"),
        ({"pilot": "nowhere"}, "is not a training run"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    monkeypatch, capsys, runs: Path, change: dict[str, str], message: str
) -> None:
    args = _args(runs, **change)
    if change == {"baseline": "adv0"}:  # list adv0 once only, as a baseline
        i = args.index("--advised")
        del args[i : i + 2]
    code, _, err = acv(monkeypatch, capsys, *args)
    assert code == 2 and message in err and err.count("\n") == 1


def test_bad_margin_and_judge(monkeypatch, capsys, runs: Path) -> None:
    code, _, err = acv(monkeypatch, capsys, *_args(runs), "--margin-advice", "2")
    assert code == 2 and "--margin-advice must be in [0, 1]" in err
    args = _args(runs)
    args[-1] = "nonsense"
    code, _, err = acv(monkeypatch, capsys, *args)
    assert code == 2 and "unknown judge" in err


def test_immediate_r_contested_uses_the_pilot_judges_r(monkeypatch, capsys, runs: Path) -> None:
    from engine.treefile import load_tree
    from engine.verdict_runs import judges_reward

    advice = load_tree(runs / "human.json")
    r = judges_reward([runs / "pilot7"], advice)
    stored = np.array([c.env_reward for c in advice.candidates])
    assert (r < stored).all()  # minus the control cost of the pilot's actions
    code, out, err = acv(monkeypatch, capsys, *_args(runs), "--json")
    assert code == 0, err
    m = json.loads(out)["matches"]
    informative = [tuple(p) for p in m["contested"] + m["agreed"]]
    expected = [(a, b, w) for a, b, w in informative if r[w] < r[b if w == a else a]]
    assert [tuple(p) for p in m["r_contested"]] == expected


def test_the_legacy_value_judge_is_shaped_value(monkeypatch, capsys, runs: Path) -> None:
    args = _args(runs)
    args[-1] = "value"
    code, legacy, err = acv(monkeypatch, capsys, *args, "--json")
    assert code == 0, err
    args[-1] = "shaped-value"
    code, current, err = acv(monkeypatch, capsys, *args, "--json")
    assert code == 0, err
    assert json.loads(legacy) == json.loads(current)


def test_runs_show_their_hparams_and_the_verdict_in_tensorboard(
    monkeypatch, capsys, runs: Path
) -> None:
    for name, algo, seed in (("adv0", "ppo-shaped", 0), ("pilot7", "ppo", 7)):
        logged = hparams(runs / name)
        assert (logged["algo"], logged["seed"], logged["env_id"]) == (algo, seed, "Hopper-v5")
        assert logged["norm_obs"] == "true" and logged["pool_weights"] == "none"
    code, out, err = acv(monkeypatch, capsys, *_args(runs), "--json")
    assert code == 0, err
    v = json.loads(out)
    low, high = v["interval"] or (None, None)
    design = {
        "delta": v["delta"],
        "interval_low": low,
        "interval_high": high,
        "p_value": v["p_value"],
        "auc": v["auc"],
        "contested": len(v["matches"]["contested"]),
        "min_detectable_delta": v["min_detectable_delta"],
    }
    design = {k: x for k, x in design.items() if x is not None}
    judged = max(list_checkpoints(runs / "adv0"))
    for name, arm, extra in (("adv0", "ca_advised", design), ("base1", "ca_baseline", {})):
        own = {"ca": v[arm][0 if name == "adv0" else 1]} if v[arm] else {}
        logged = last_scalars(runs / name, "verdict/shaped/")
        assert logged == {k: (judged, pytest.approx(x, abs=1e-6)) for k, x in (own | extra).items()}
    assert "verdict/shaped/text_summary" in events(runs / "adv0").Tags()["tensors"]
    assert last_scalars(runs / "pilot7", "verdict/") == {}  # it only picked the matches

    before = sorted((runs / "adv1").glob("events.out.tfevents.*"))
    code, _, err = acv(monkeypatch, capsys, *_args(runs), "--no-tensorboard")
    assert code == 0, err
    assert sorted((runs / "adv1").glob("events.out.tfevents.*")) == before
