"""Learning benchmark: ACV ``ppo`` next to Stable-Baselines3 PPO, same settings, same seeds.

Both learners train on the same env with the same hyper-parameters: env count, rollout length,
epochs, minibatch size, learning rate annealed linearly to 0, GAE, clipping, 2x64 tanh
networks, observation and reward normalisation (clip 10), Adam eps 1e-5. The score of each
is the mean true return of its last 100 episodes. ACV's target is >= 700 after 1M steps, the
mean over seeds (CleanRL's PPO reaches 716 +/- 49 on Humanoid-v4, which has no contact cost).

    .venv/bin/python benchmarks/learning.py --timesteps 1000000 --seeds 0 1 2 \
        [--acv-runs results/runs/ppo] [--jobs 2]

``--acv-runs`` reuses finished ACV runs (``seed_<k>`` folders of ``ppo`` runs, from ``acv
reproduce`` for one, whose configuration is checked to be the one this benchmark would train)
instead of training them again; ``--acv-validation`` reads them from an ``acv validate``
folder's measures of its ``n1`` runs, so their folders need not be there. ``--sb3-only``
trains and keeps SB3's seeds in ``--out`` and stops, so that they can train while ACV's runs
still do; the same command without it then reuses them. The last line is one JSON object:
``acv_return``, ``sb3_return`` (means over seeds), ``ratio_vs_sb3``, per-seed returns,
Student's t 95% intervals over seeds, Welch's interval of the difference (descriptive) and
``reference_cleanrl_humanoid_v4``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from engine.rl.config import TrainConfig

CLEANRL_HUMANOID_1M = 716.0  # CleanRL ppo_continuous_action, Humanoid-v4, 1M steps (mean)
TARGET = 700.0


def _settings(cfg: TrainConfig) -> dict:
    """What makes two runs comparable: every setting but how often they checkpoint."""
    return cfg.to_json() | {"checkpoint_every": 0}


def validation_return(cfg: TrainConfig, folder: Path) -> float:
    """The return of an ``acv validate`` folder's no-advice run ``n1`` at ``cfg.seed``, read
    from its measures (the run's folder may be on another machine); the validation's plan
    must have trained it with this benchmark's settings."""
    from engine.validation.design import ARM_BY_NAME, BASELINE, Plan
    from engine.validation.runs import measures_path, read_json, train_config

    plan = Plan.from_json(read_json(folder / "validate.json"))
    if _settings(train_config(plan, ARM_BY_NAME[BASELINE], cfg.seed)) != _settings(cfg):
        raise SystemExit(f"{folder}'s n1 runs were trained with other settings than these")
    path = measures_path(folder, (BASELINE, cfg.seed))
    if not path.is_file():
        raise SystemExit(f"{folder} has not measured n1 at seed {cfg.seed} yet")
    return float(read_json(path)["train"]["return_100"])


def acv_return(cfg: TrainConfig, out: Path, reuse: Path | None) -> float:
    """ACV's mean return of the last 100 episodes, training unless ``reuse`` holds the run
    (a run folder, or an ``acv validate`` folder whose ``n1`` runs are measured)."""
    from engine.rl.logger import read_metrics
    from engine.rl.runner import load_run_config, train

    if reuse is not None and (reuse / "validate.json").is_file():
        return validation_return(cfg, reuse)
    if reuse is not None:
        if _settings(load_run_config(reuse)) != _settings(cfg):
            raise SystemExit(f"{reuse} was trained with other settings than this benchmark's")
        rows = read_metrics(reuse)
    else:
        train(cfg, None, out)
        rows = read_metrics(out)
    if rows[-1]["timesteps"] < cfg.total_timesteps:
        raise SystemExit(f"{reuse or out} stopped at {rows[-1]['timesteps']} steps")
    return float(rows[-1]["return_100"])


def sb3_return(cfg: TrainConfig) -> float:
    """Stable-Baselines3 PPO with ``cfg``'s settings: mean return of its last 100 episodes."""
    import gymnasium as gym
    import torch
    from stable_baselines3.common.env_util import make_vec_env

    from engine.rl.sb3_peer import normalised, sb3_ppo

    torch.set_num_threads(1)
    venv = make_vec_env(lambda: gym.make(cfg.env_id), n_envs=cfg.n_envs, seed=cfg.seed)
    model = sb3_ppo(cfg, normalised(venv, cfg))
    model.learn(total_timesteps=cfg.num_updates * cfg.batch_size)
    return float(np.mean([info["r"] for info in model.ep_info_buffer]))


def sb3_kept(cfg: TrainConfig, out: Path) -> float:
    """SB3's return at ``cfg``, trained once and kept in ``out/sb3_seed_<k>.<env>.<steps>.json``
    (with its wall time), so a second call with the same ``--out`` reuses it."""
    cached = out / f"sb3_seed_{cfg.seed}.{cfg.env_id}.{cfg.total_timesteps}.json"
    if cached.is_file():
        return float(json.loads(cached.read_text())["sb3"])
    start = time.perf_counter()
    sb3 = sb3_return(cfg)
    out.mkdir(parents=True, exist_ok=True)
    cached.write_text(json.dumps({"sb3": sb3, "wall_s": time.perf_counter() - start}))
    return sb3


def one_seed(cfg: TrainConfig, out: Path, reuse: Path | None) -> dict[str, float]:
    """Both learners at one seed (run in a worker process)."""
    start = time.perf_counter()
    sb3 = sb3_kept(cfg, out)
    mid = time.perf_counter()
    acv = acv_return(cfg, out / f"acv_seed_{cfg.seed}", reuse)
    result = {
        "seed": cfg.seed,
        "acv": round(acv, 1),
        "sb3": round(sb3, 1),
        "sb3_wall_s": round(mid - start, 1),
        "acv_wall_s": round(time.perf_counter() - mid, 1),
    }
    print(json.dumps(result), flush=True)
    return result


def interval(values: list[float]) -> list[float] | None:
    """Student's t 95% interval of the mean over seeds (None for one seed)."""
    from scipy import stats

    x = np.asarray(values)
    if len(x) < 2 or stats.sem(x) == 0:
        return None
    low, high = stats.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=stats.sem(x))
    return [round(float(low), 1), round(float(high), 1)]


def welch_interval(acv: list[float], sb3: list[float]) -> dict[str, Any] | None:
    """Welch's 95% interval of ACV's mean minus SB3's (unequal variances), and its p: a
    description of these seeds, not a test of a hypothesis declared before them."""
    from scipy import stats

    if min(len(acv), len(sb3)) < 2:
        return None
    test = stats.ttest_ind(acv, sb3, equal_var=False)
    low, high = test.confidence_interval(0.95)
    return {
        "difference": round(float(np.mean(acv) - np.mean(sb3)), 1),
        "ci95": [round(float(low), 1), round(float(high), 1)],
        "p": round(float(test.pvalue), 3),
        "df": round(float(test.df), 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument(
        "--acv-runs",
        type=Path,
        default=None,
        help="folder of finished ACV ppo runs seed_<k> to reuse",
    )
    parser.add_argument(
        "--acv-validation",
        type=Path,
        default=None,
        help="an acv validate folder whose measured n1 runs to reuse",
    )
    parser.add_argument("--jobs", type=int, default=1, help="seeds trained at a time")
    parser.add_argument("--out", type=Path, default=None, help="ACV run folder (default: temp)")
    parser.add_argument("--sb3-only", action="store_true", help="train and keep SB3's seeds only")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acv-learning-"))
    configs = [
        TrainConfig(algo="ppo", env_id=args.env, total_timesteps=args.timesteps, seed=seed)
        for seed in args.seeds
    ]
    if args.sb3_only:
        with ProcessPoolExecutor(max_workers=args.jobs, mp_context=get_context("spawn")) as pool:
            kept = list(pool.map(sb3_kept, configs, [out] * len(configs)))
        print(json.dumps({"env": args.env, "seeds": args.seeds, "sb3_returns": kept}))
        return
    reuse = [
        args.acv_validation or (args.acv_runs / f"seed_{c.seed}" if args.acv_runs else None)
        for c in configs
    ]
    with ProcessPoolExecutor(max_workers=args.jobs, mp_context=get_context("spawn")) as pool:
        rows = list(pool.map(one_seed, configs, [out] * len(configs), reuse))
    acv, sb3 = [r["acv"] for r in rows], [r["sb3"] for r in rows]
    print(
        json.dumps(
            {
                "env": args.env,
                "timesteps": args.timesteps,
                "seeds": args.seeds,
                "acv_return": round(float(np.mean(acv)), 1),
                "sb3_return": round(float(np.mean(sb3)), 1),
                "ratio_vs_sb3": round(float(np.mean(acv) / np.mean(sb3)), 3),
                "acv_returns": acv,
                "sb3_returns": sb3,
                "acv_ci95_t": interval(acv),
                "sb3_ci95_t": interval(sb3),
                "acv_minus_sb3_welch": welch_interval(acv, sb3),
                "acv_spread_sd": round(float(np.std(acv, ddof=1)), 1) if len(acv) > 1 else None,
                "target": TARGET,
                "reference_cleanrl_humanoid_v4": CLEANRL_HUMANOID_1M,
                "acv_reused": str(args.acv_validation or args.acv_runs or "") or None,
            }
        )
    )


if __name__ == "__main__":
    main()
