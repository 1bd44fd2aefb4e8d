"""Stable-Baselines3 PPO with a :class:`~engine.rl.config.TrainConfig`'s settings: the peer
that ACV's benchmarks compare with (``benchmarks/learning.py``, ``train_throughput.py``,
``sb3_advice.py``, ``run_cost.py``'s ``sb3`` stage), built in one place so that they compare
with the same learner.

The same settings as ACV's PPO: env count, rollout length, epochs, minibatch size, learning
rate (annealed linearly to 0 when the config says so), GAE, clipping, 2x64 tanh networks,
observation and reward normalisation clipped at 10, Adam eps 1e-5, on the CPU.
Stable-Baselines3 is imported only when a peer is built: it is no dependency of the product.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from engine.rl.config import TrainConfig

if TYPE_CHECKING:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnv, VecNormalize

#: VecNormalize's clip of normalised observations and rewards, as ACV's normalisation.
CLIP = 10.0


def normalised(venv: VecEnv, cfg: TrainConfig) -> VecNormalize:
    """``venv`` with SB3's running observation and reward normalisation, as ``cfg`` asks."""
    from stable_baselines3.common.vec_env import VecNormalize

    return VecNormalize(
        venv,
        norm_obs=cfg.norm_obs,
        norm_reward=cfg.norm_reward,
        clip_obs=CLIP,
        clip_reward=CLIP,
        gamma=cfg.gamma,
    )


def sb3_ppo(cfg: TrainConfig, venv: VecEnv, *, anneal: bool | None = None) -> PPO:
    """SB3 PPO on ``venv`` with ``cfg``'s settings; ``anneal`` overrides ``cfg.anneal_lr``
    (a throughput bench times a constant rate)."""
    from stable_baselines3 import PPO
    from torch import nn

    lr = cfg.learning_rate
    annealed = cfg.anneal_lr if anneal is None else anneal
    schedule: Any = (lambda left: lr * left) if annealed else lr
    return PPO(
        "MlpPolicy",
        venv,
        learning_rate=schedule,
        n_steps=cfg.num_steps,
        batch_size=cfg.minibatch_size,
        n_epochs=cfg.update_epochs,
        gamma=cfg.gamma,
        gae_lambda=cfg.gae_lambda,
        clip_range=cfg.clip_coef,
        ent_coef=cfg.ent_coef,
        vf_coef=cfg.vf_coef,
        max_grad_norm=cfg.max_grad_norm,
        device="cpu",
        seed=cfg.seed,
        policy_kwargs={
            "net_arch": {"pi": [cfg.hidden] * 2, "vf": [cfg.hidden] * 2},
            "activation_fn": nn.Tanh,
            "optimizer_kwargs": {"eps": 1e-5},
        },
    )
