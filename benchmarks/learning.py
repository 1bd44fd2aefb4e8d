"""Learning benchmark: ACV ``ppo`` on Humanoid-v5, mean true return of the last 100 episodes.

Target: >= 700 after 1M steps (CleanRL's PPO reaches 716 +/- 49 on Humanoid-v4 at 1M steps,
the reference this script divides by). Takes 10-20 minutes on two cores:

    .venv/bin/python benchmarks/learning.py --timesteps 1000000 [--seed 0] [--out DIR]

Prints the return every ``--every`` steps and, last, one JSON object.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from engine.rl.config import TrainConfig
from engine.rl.runner import train

CLEANRL_HUMANOID_1M = 716.0  # CleanRL ppo_continuous_action, Humanoid-v4, 1M steps (mean)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=1_000_000)
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument("--algo", default="ppo")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-envs", type=int, default=TrainConfig.n_envs)
    parser.add_argument("--num-steps", type=int, default=TrainConfig.num_steps,
                        help="steps per env per rollout")
    parser.add_argument("--every", type=int, default=50_000, help="print period in steps")
    parser.add_argument("--out", type=Path, default=None, help="run directory (default: temp)")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="acv-learning-")) / "run"
    cfg = TrainConfig(algo=args.algo, env_id=args.env, total_timesteps=args.timesteps,
                      seed=args.seed, n_envs=args.n_envs, num_steps=args.num_steps,
                      checkpoint_every=max(args.timesteps, 1))
    last: dict = {}

    def progress(row: dict) -> None:
        if row["timesteps"] // args.every > (row["timesteps"] - cfg.batch_size) // args.every:
            print(f"{row['timesteps']:>9d} steps  return(100) {row['return_100'] or 0:8.1f}  "
                  f"{row['sps']:6.0f} steps/s", flush=True)
        last.update(row)

    start = time.perf_counter()
    train(cfg, None, out, progress=progress)
    result = {"env": args.env, "algo": args.algo, "seed": args.seed, "n_envs": cfg.n_envs,
              "num_steps": cfg.num_steps,
              "timesteps": last["timesteps"],
              "mean_return_last100": round(last["return_100"], 1),
              "target": 700.0, "reference_cleanrl_humanoid_v4": CLEANRL_HUMANOID_1M,
              "ratio_vs_reference": round(last["return_100"] / CLEANRL_HUMANOID_1M, 3),
              "sps": round(last["sps"], 1), "wall_s": round(time.perf_counter() - start, 1),
              "run_dir": str(out)}
    print(json.dumps(result))


if __name__ == "__main__":
    main()
