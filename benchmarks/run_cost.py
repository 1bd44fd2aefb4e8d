"""The cost of a run where users wait: a late checkpoint resumed with the product's schedule.

``source`` trains the source run once, outside the repository (``bipars-em`` on Humanoid-v5, a
1M-step config stopped early: "late" only as far as this machine allows). ``measure`` times
each stage in a fresh process: ``env`` (the run's envs and F, random actions), fresh learners
``learner-ppo`` and ``learner-em`` (``train_throughput.py``'s loop), ``learner-2proc`` (the
``learner-em`` loop with half of the envs in a helper process: wall steps/s),
``learner-resumed`` (that loop from the source checkpoint), ``run`` (``train(resume=True)`` on
a copy of the source for ``--steps``, with a checkpoint every ``checkpoint_every`` steps and at
the stop, each judged by ``checkpoint_report`` as the worker's ``on_checkpoint`` does, metrics
and TensorBoard logged) and ``sb3`` (Stable-Baselines3 PPO, same settings, when installed).
Learners also report their env CPU seconds, so that "env share" compares code within one
process whatever the machine's speed; ``run`` reports its startup, judging and checkpoint
seconds and projects them to 100k steps at the product's density. Each ``--code`` checkout
(``PYTHONPATH``) runs every stage once per repeat, alternating; ratios are per repeat, printed
as median [range]. The last line is one JSON object. Commands and results: ``docs/scale.md``,
"The cost of a training run".

    .venv/bin/python benchmarks/run_cost.py source --out /work/runs/run-cost/source
    .venv/bin/python benchmarks/run_cost.py measure --source /work/runs/run-cost/source \\
        [--steps 100000] [--other-steps 40960] [--repeats 3] [--code /path/to/old --code .] \\
        [--stages run env] [--last-only env]
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
ADVICE = ROOT / "tests" / "engine" / "rl" / "data" / "bit_identity" / "advice.json"
STAGES = (
    "env",
    "learner-ppo",
    "learner-em",
    "learner-2proc",
    "learner-resumed",
    "run",
    "run-2proc",
    "sb3",
)
#: (numerator, denominator) stages of the ratios printed within one checkout.
RATIOS = {
    "learner/env": ("learner-em", "env"),
    "run/env": ("run", "env"),
    "run/learner": ("run", "learner-resumed"),
    "ppo/sb3": ("learner-ppo", "sb3"),
    "ppo/em (BiPaRS overhead + 1)": ("learner-ppo", "learner-em"),
}
#: The same, of wall-clock steps/s: ``learner-2proc`` spends a second process's CPU on purpose.
WALL_RATIOS = {
    "2proc/1proc (wall)": ("learner-2proc", "learner-em"),
    "run 2proc/1proc (wall)": ("run-2proc", "run"),
}
#: A two-process stage of the new code, against the one-process stage of the old.
ONE_PROCESS = {"learner-2proc": "learner-em", "run-2proc": "run"}


def make_source(out: Path, algo: str, steps: int, seed: int) -> None:
    """Train the source run: a 1M-step config of ``algo`` stopped after ``steps`` steps. An
    existing source is resumed from its last checkpoint up to ``steps`` (made later)."""
    from engine.rl.checkpoint import list_checkpoints
    from engine.rl.config import TrainConfig
    from engine.rl.runner import train
    from engine.treefile import load_tree

    cfg = TrainConfig(algo=algo, seed=seed)
    done = max(list_checkpoints(out), default=0) if out.is_dir() else 0
    updates = -(-steps // cfg.batch_size) - done // cfg.batch_size
    calls = iter(range(1, updates + 1))
    advice = None if done else load_tree(ADVICE)
    train(cfg, advice, out, should_stop=lambda: next(calls) >= updates, resume=bool(done))


def _clock() -> np.ndarray:
    return np.array([time.process_time(), time.perf_counter()])


def _source_config(source: Path, algo: str | None = None) -> Any:
    from engine.rl.config import TrainConfig
    from engine.rl.runner import load_run_config

    cfg = load_run_config(source)
    return cfg if algo is None else TrainConfig(**{**cfg.__dict__, "algo": algo})


def _advice(source: Path, cfg: Any) -> Any:
    from engine.rl.runner import _advice_fn, load_run_advice

    return _advice_fn(cfg, load_run_advice(source)) if cfg.uses_advice else None


def stage_env(source: Path, steps: int) -> dict[str, float]:
    """The run's vector env (advice included) under uniform random actions."""
    from engine.rl.vecenv import make_vec_env

    cfg = _source_config(source)
    envs = make_vec_env(
        cfg.env_id, cfg.n_envs, _advice(source, cfg), cfg.advice_scale, cfg.advice_offset
    )
    envs.reset(seed=cfg.seed)
    envs.action_space.seed(cfg.seed)
    start = _clock()
    for _ in range(-(-steps // cfg.n_envs)):
        envs.step(envs.action_space.sample())
    return _result(start, -(-steps // cfg.n_envs) * cfg.n_envs)


def stage_learner(
    source: Path, steps: int, algo: str | None, resumed: bool, processes: int = 1
) -> dict[str, float]:
    """``Trainer.iterate`` alone: no logging, checkpoints or judging. With ``processes=2``
    (``learner-2proc``), half of the envs step in a helper process: compare its wall
    steps/s; its CPU seconds are the learner's only, and its env seconds include the wait."""
    import torch

    from engine.rl.checkpoint import find_checkpoint, load_checkpoint
    from engine.rl.trainer import Trainer

    torch.set_num_threads(1)
    cfg = _source_config(source, algo)
    split = {"env_processes": processes} if processes > 1 else {}  # old code lacks it
    trainer = Trainer(cfg, _advice(source, cfg), **split)
    if resumed:
        trainer.load_state_dict(load_checkpoint(find_checkpoint(source)))
    spent = {"collect_cpu_s": 0.0, "env_cpu_s": 0.0}
    collector = trainer.collector  # timed in place: the same calls, with a clock around them
    cpu = time.process_time
    collector.collect = _timed(collector.collect, spent, "collect_cpu_s", cpu)  # type: ignore[method-assign]
    collector.envs.step = _timed(collector.envs.step, spent, "env_cpu_s", cpu)  # type: ignore[method-assign]
    start, first = _clock(), trainer.timesteps
    while trainer.timesteps - first < steps:
        trainer.iterate()
    result = _result(start, trainer.timesteps - first) | spent
    trainer.close()
    return result


def _timed(
    fn: Callable[..., Any], spent: dict[str, float], key: str, clock: Callable[[], float]
) -> Callable[..., Any]:
    """``fn``, adding its seconds by ``clock`` to ``spent[key]`` and counting its calls."""

    def call(*args: Any) -> Any:
        t = clock()
        try:
            return fn(*args)
        finally:
            spent[key] += clock() - t
            spent[f"{key}_calls"] = spent.get(f"{key}_calls", 0) + 1

    return call


def stage_run(source: Path, steps: int, processes: int = 1) -> dict[str, float]:
    """Resume a copy of the source through ``train`` with checkpoints and their judging (with
    ``processes=2``, ``run-2proc``: half of the envs in a helper process, as the worker's
    ``ACV_SPLIT_LONE_RUN``)."""
    import engine.rl.runner as runner
    from engine.rl.report import checkpoint_report

    cfg = _source_config(source)
    spent = {"save_s": 0.0, "judge_s": 0.0}
    wall = time.perf_counter
    updates = -(-steps // cfg.batch_size)
    calls = iter(range(1, updates + 1))
    runner.save_checkpoint = _timed(runner.save_checkpoint, spent, "save_s", wall)  # type: ignore[attr-defined]
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        shutil.copytree(source, run, ignore=shutil.ignore_patterns("rollouts"))
        rows: list[float] = []
        start = _clock()
        runner.train(
            cfg,
            None,
            run,
            progress=lambda _: rows.append(time.perf_counter()),
            should_stop=lambda: next(calls) >= updates,
            resume=True,
            on_checkpoint=_timed(lambda s, _: checkpoint_report(run, s), spent, "judge_s", wall),
            **({"env_processes": processes} if processes > 1 else {}),  # as in stage_learner
        )
        result = _result(start, updates * cfg.batch_size)
    # the resume's start (imports, loading, envs, TensorBoard): up to the first row, less one
    # update (the median time between rows)
    spent["startup_s"] = rows[0] - start[1] - statistics.median(np.diff(rows))
    loop_s = result["wall_s"] - spent["save_s"] - spent["judge_s"] - spent["startup_s"]
    judged = spent.get("judge_s_calls", 0)
    per_ckpt = spent["save_s"] / spent["save_s_calls"] + (
        spent["judge_s"] / judged if judged else float("nan")
    )
    projected = loop_s / result["steps"] * 100_000 + 100_000 / cfg.checkpoint_every * per_ckpt
    return result | spent | {"projected_wall_s_per_100k": projected}


def stage_sb3(source: Path, steps: int) -> dict[str, float]:
    """Stable-Baselines3 PPO with the source's settings (``train_throughput``'s setup)."""
    import torch

    torch.set_num_threads(1)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    sb3_timer = importlib.import_module("train_throughput").sb3_timer  # a script, not a package

    cfg = _source_config(source, "ppo")
    updates = -(-steps // cfg.batch_size)
    return _result(_clock() - sb3_timer(cfg)(updates), updates * cfg.batch_size)


def _result(start: np.ndarray, steps: int) -> dict[str, float]:
    """CPU and wall seconds since ``start``, and steps per second of each."""
    cpu, wall = _clock() - start
    return {
        "cpu_s": cpu,
        "wall_s": wall,
        "steps": steps,
        "cpu_sps": steps / cpu,
        "wall_sps": steps / wall,
    }


def child(stage: str, source: Path, steps: int, profile: Path | None) -> dict[str, float]:
    """Run one stage in this process (optionally under cProfile, stats dumped to ``profile``)."""
    run: Callable[[], dict[str, float]] = {
        "env": lambda: stage_env(source, steps),
        "learner-ppo": lambda: stage_learner(source, steps, "ppo", False),
        "learner-em": lambda: stage_learner(source, steps, None, False),
        "learner-2proc": lambda: stage_learner(source, steps, None, False, processes=2),
        "learner-resumed": lambda: stage_learner(source, steps, None, True),
        "run": lambda: stage_run(source, steps),
        "run-2proc": lambda: stage_run(source, steps, processes=2),
        "sb3": lambda: stage_sb3(source, steps),
    }[stage]
    if profile is None:
        return run()
    import cProfile

    with cProfile.Profile() as prof:  # wall time: its fractions, not its seconds, are read
        result = run()
    prof.dump_stats(profile)
    return result


def spawn(code: Path, stage: str, source: Path, steps: int) -> dict[str, float]:
    """One stage in a fresh process importing ``engine`` from the checkout ``code``."""
    env = os.environ | {"PYTHONPATH": str(code)}
    cmd = [sys.executable, __file__, "child", stage, str(source), str(steps)]
    out = subprocess.run(cmd, env=env, cwd=code, check=True, capture_output=True, text=True)
    result: dict[str, float] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def spread(values: list[float]) -> str:
    """``median [min-max]``."""
    return f"{statistics.median(values):.3f} [{min(values):.3f}-{max(values):.3f}]"


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Alternate checkouts and stages ``--repeats`` times; print per-run lines and ratios."""
    codes = [Path(c).resolve() for c in args.code] or [ROOT]
    stages = [s for s in args.stages if s != "sb3" or _has_sb3()]
    got: dict[str, dict[str, list[dict[str, float]]]] = {str(c): {} for c in codes}
    for r in range(args.repeats):
        for code in codes:
            for stage in stages:
                if stage in args.last_only and code != codes[-1]:
                    continue
                steps = args.steps if stage.startswith("run") else args.other_steps
                res = spawn(code, stage, args.source, steps or args.steps)
                got[str(code)].setdefault(stage, []).append(res)
                extra = {
                    k: round(v, 2) for k, v in res.items() if k.endswith(("_s", "_calls", "k"))
                }
                print(
                    f"repeat {r} {code.name or code} {stage:16s} {res['cpu_sps']:7.0f} steps/CPU-s "
                    f"{res['wall_sps']:7.0f} steps/s {extra}",
                    flush=True,
                )
    summary = {code: _within(by_stage) for code, by_stage in got.items()}
    ref = got[str(codes[0])]
    for code in codes[1:]:
        summary[f"{code.name} vs {codes[0].name}: old/new"] = _versus(ref, got[str(code)])
    for key, value in summary.items():
        print(key, json.dumps(value, indent=1))
    return summary


def _learner_cost(res: dict[str, float]) -> float:
    """A learner's CPU seconds per CPU second of its own env steps (in the same process, so
    that the machine's speed, which drifts with other load, cancels out)."""
    return res["cpu_s"] / res["env_cpu_s"]


def _within(by_stage: dict[str, list[dict[str, float]]]) -> dict[str, str]:
    """One checkout's steps/s, ratios between its stages, and its learners' env shares."""
    cpu = {s: [x["cpu_sps"] for x in v] for s, v in by_stage.items()}
    out = {f"{s} cpu_sps": spread(v) for s, v in cpu.items()}
    for name, (a, b) in RATIOS.items():
        if a in cpu and b in cpu:
            out[name] = spread([x / y for x, y in zip(cpu[a], cpu[b], strict=True)])
    wall = {s: [x["wall_sps"] for x in v] for s, v in by_stage.items()}
    for name, (a, b) in WALL_RATIOS.items():
        if a in wall and b in wall:
            out[f"{a} wall_sps"] = spread(wall[a])
            out[name] = spread([x / y for x, y in zip(wall[a], wall[b], strict=True)])
    for s, v in by_stage.items():
        if "env_cpu_s" in v[0] and not s.endswith("2proc"):
            out[f"{s} env share (env CPU / learner CPU)"] = spread(
                [1 / _learner_cost(x) for x in v]
            )
    return out


def _versus(
    old: dict[str, list[dict[str, float]]], new: dict[str, list[dict[str, float]]]
) -> dict[str, str]:
    """Per repeat, old/new CPU seconds of each stage, and of each learner per env CPU second;
    a two-process stage's new/old wall seconds against the old one-process stage (the
    issue's "0.5x of today's time")."""
    out = {
        s: spread([o["cpu_s"] / n["cpu_s"] for o, n in zip(old[s], v, strict=True)])
        for s, v in new.items()
        if s in old
    }
    for s, v in new.items():
        if ONE_PROCESS.get(s) in old:
            pairs = zip(old[ONE_PROCESS[s]], v, strict=True)
            out[f"{s} vs old {ONE_PROCESS[s]}: new/old wall"] = spread(
                [n["wall_s"] / o["wall_s"] for o, n in pairs]
            )
        if s == "run" and s in old:
            pairs = zip(old[s], v, strict=True)
            out["run: new/old wall"] = spread([n["wall_s"] / o["wall_s"] for o, n in pairs])
        if "env_cpu_s" in v[0] and s in old:
            pairs = zip(old[s], v, strict=True)
            out[f"{s} per env CPU"] = spread(
                [_learner_cost(o) / _learner_cost(n) for o, n in pairs]
            )
    return out


def _has_sb3() -> bool:
    return importlib.util.find_spec("stable_baselines3") is not None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    src = sub.add_parser("source", help="train the source run once")
    for name, kind, default in (
        ("out", Path, None),
        ("algo", str, "bipars-em"),
        ("steps", int, 190_000),
        ("seed", int, 0),
    ):
        src.add_argument(f"--{name}", type=kind, default=default, required=default is None)
    mes = sub.add_parser("measure", help="time every stage, alternating checkouts")
    mes.add_argument("--source", type=Path, required=True)
    mes.add_argument("--steps", type=int, default=100_000)
    mes.add_argument(
        "--other-steps", type=int, default=0, help="steps of the stages but run (default --steps)"
    )
    mes.add_argument("--repeats", type=int, default=3)
    mes.add_argument("--code", action="append", default=[], help="a checkout (repeatable)")
    mes.add_argument("--stages", nargs="+", default=list(STAGES), choices=STAGES)
    mes.add_argument(
        "--last-only",
        nargs="+",
        default=[],
        choices=STAGES,
        help="stages measured with the last --code only (the new code's own, or not code's)",
    )
    one = sub.add_parser("child", help="one stage in this process (used by measure)")
    one.add_argument("stage", choices=STAGES)
    for name, kind in (("source", Path), ("steps", int)):
        one.add_argument(name, type=kind)
    one.add_argument("--profile", type=Path, help="write cProfile stats here")
    args = parser.parse_args()
    if args.cmd == "source":
        make_source(args.out, args.algo, args.steps, args.seed)
    elif args.cmd == "measure":
        print(json.dumps(measure(args)))
    else:
        print(json.dumps(child(args.stage, args.source.resolve(), args.steps, args.profile)))


if __name__ == "__main__":
    main()
