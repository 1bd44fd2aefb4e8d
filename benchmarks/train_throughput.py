"""Training throughput: ACV ``ppo`` vs Stable-Baselines3 PPO, and ``bipars-em`` vs ``ppo``.

Same env, number of envs and PPO hyper-parameters on both sides (2x64 tanh MLPs, rollout of
``--num-steps`` per env, ``--epochs`` epochs of minibatches of ``--minibatch`` transitions,
observation and reward normalisation, torch threads = 1). Each side runs ``--updates``
rollout+update iterations per round after a warm-up round, and the sides alternate for
``--rounds`` rounds, so that machine noise hits them alike. Everything runs in one thread, so
the ratios use the process CPU time (robust to other load on the machine); wall-clock steps/s
are printed too. Prints one line per measurement and, last, one JSON object with ``acv_sps``,
``sb3_sps``, ``ratio_vs_sb3`` and ``bipars_overhead`` (bipars time / ppo time - 1), plus
the wall-clock ratios. Targets (2 cores): ratio >= 1.2, overhead <= 0.15.

    .venv/bin/python benchmarks/train_throughput.py [--env Humanoid-v5] [--n-envs 4]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from engine.pipeline import run_tournament
from engine.rl.advice_fn import advice_reward
from engine.rl.config import TrainConfig
from engine.rl.trainer import Trainer


def clocks() -> np.ndarray:
    """(CPU seconds of this process, wall seconds)."""
    return np.array([time.process_time(), time.perf_counter()])


def acv_timer(cfg: TrainConfig, advice):
    """A function that runs ``k`` ACV iterations and returns their (CPU, wall) seconds."""
    trainer = Trainer(cfg, advice)

    def run(k: int) -> np.ndarray:
        start = clocks()
        for _ in range(k):
            trainer.iterate()
        return clocks() - start

    return run


def sb3_timer(cfg: TrainConfig):
    """The same for Stable-Baselines3 PPO with matching settings."""
    import gymnasium as gym
    from stable_baselines3.common.env_util import make_vec_env

    from engine.rl.sb3_peer import normalised, sb3_ppo

    venv = make_vec_env(
        lambda: gym.make(cfg.env_id, disable_env_checker=True), n_envs=cfg.n_envs, seed=cfg.seed
    )
    model = sb3_ppo(cfg, normalised(venv, cfg), anneal=False)  # a constant rate, timed

    def run(k: int) -> np.ndarray:
        start = clocks()
        model.learn(total_timesteps=k * cfg.batch_size, reset_num_timesteps=False)
        return clocks() - start

    return run


def measure(timers: dict, updates: int, rounds: int, steps: int) -> dict[str, np.ndarray]:
    """Alternate the timers; return each one's (CPU, wall) steps per second over all rounds."""
    for run in timers.values():
        run(1)  # warm-up: first-call imports and allocations
    total = {name: np.zeros(2) for name in timers}
    for r in range(rounds):
        for name, run in timers.items():
            seconds = run(updates)
            total[name] += seconds
            cpu, wall = updates * steps / seconds
            print(f"round {r}: {name:10s} {cpu:6.0f} steps/CPU-s {wall:6.0f} steps/s", flush=True)
    return {name: rounds * updates * steps / t for name, t in total.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="Humanoid-v5")
    parser.add_argument("--n-envs", type=int, default=4)
    parser.add_argument("--num-steps", type=int, default=512)
    parser.add_argument("--minibatch", type=int, default=64)
    parser.add_argument("--epochs", type=int, default=10)
    parser.add_argument("--updates", type=int, default=2, help="iterations per round")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)
    base = dict(
        env_id=args.env,
        n_envs=args.n_envs,
        num_steps=args.num_steps,
        num_minibatches=args.n_envs * args.num_steps // args.minibatch,
        update_epochs=args.epochs,
    )
    ppo, em = TrainConfig(algo="ppo", **base), TrainConfig(algo="bipars-em", **base)
    tree = run_tournament(env_id=args.env, n_candidates=16, p=0.9, seed=0, teacher="good")
    sps = measure(
        {
            "acv-ppo": acv_timer(ppo, None),
            "sb3-ppo": sb3_timer(ppo),
            "acv-bipars": acv_timer(em, advice_reward(em, tree)),
        },
        args.updates,
        args.rounds,
        ppo.batch_size,
    )
    acv, sb3, em = sps["acv-ppo"], sps["sb3-ppo"], sps["acv-bipars"]
    result = {
        "env": args.env,
        "n_envs": args.n_envs,
        "acv_sps": round(acv[0], 1),
        "sb3_sps": round(sb3[0], 1),
        "ratio_vs_sb3": round(acv[0] / sb3[0], 3),
        "bipars_sps": round(em[0], 1),
        "bipars_overhead": round(acv[0] / em[0] - 1, 3),
        "wall_acv_sps": round(acv[1], 1),
        "wall_sb3_sps": round(sb3[1], 1),
        "wall_ratio_vs_sb3": round(acv[1] / sb3[1], 3),
        "wall_bipars_overhead": round(acv[1] / em[1] - 1, 3),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
